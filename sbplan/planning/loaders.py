"""Obstacle loaders: sbplan detection JSON, GeoJSON, nav2 map.yaml and occupancy images.

Every loader returns an :class:`ObstacleSet` in the world frame: ``(x, y)`` metres (or pixels with
resolution 1), x right, y up. Occupancy images become exact polygons (run-length rectangles of the
occupied pixels, merged by a union), never one rectangle around a connected wall structure.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import shapely
import shapely.affinity
import yaml
from shapely.geometry import Polygon, box

from .. import limits
from ..errors import ImageError, InputError, MapFormatError
from ..imageio import as_gray, image_text, load_image, read_image
from ..workspace import Georeference

if TYPE_CHECKING:
    from ..detection import Detection


@dataclass
class ObstacleSet:
    """Obstacles (shapely polygons, world frame) and the workspace bounds (xmin, ymin, xmax, ymax)
    when the source gives them."""

    polygons: list
    bounds: tuple | None = None
    source: str = ""


def load_obstacles(path: Any, *, resolution: float | None = None, use: str | None = None,
                   obstacle_model: str | None = None, image_anywhere: bool = False) -> ObstacleSet:
    """Load obstacles from a file, by its type.

    Parameters
    ----------
    path : str or Path
        ``*.json`` sbplan detection result (``format`` ``sbplan.detection/1``) or GeoJSON
        FeatureCollection; ``*.geojson`` (local metres, or WGS84 lon/lat when its ``sbplan``
        member carries the floor's georeference, mapped back to metres); ``*.yaml``/``*.yml``
        nav2 map (``mode`` trinary, scale or raw, with ``negate``, read as map_server reads them:
        :func:`map_server_values`; every cell it does not load as free is an obstacle);
        ``*.png``/``*.pgm``/... plain occupancy image (dark = occupied). sbplan's own camera-pixel
        images (the occupancy image, the overlay) and a nav2 map's image without its map.yaml
        are refused: they say what they are in their metadata.
    resolution : float, optional
        Metres per pixel for a plain image (default 1: pixel units). Origin at the image's
        bottom-left corner, y up (nav2's frame).
    obstacle_model : "mar" | "parts" | "outline"
        What of a detection result to plan around (:mod:`sbplan.detection.obstacles`); default
        ``parts``. A GeoJSON file says which model it was written with (default: its MARs).
    use : str
        The old name of ``obstacle_model``.
    image_anywhere : bool
        A nav2 map.yaml's ``image:`` may name a file outside the YAML's folder (by default it must
        lie inside it: a map file is data, not a key to the file system).

    Raises
    ------
    MapFormatError
        Missing, unreadable or malformed file, or a value that is out of range.
    LimitError
        An occupancy image with more runs of occupied pixels than the ``obstacle_vertices`` limit.
    """
    if resolution is not None and not (isinstance(resolution, (int, float)) and math.isfinite(resolution)
                                       and resolution > 0):
        raise InputError(f"resolution (--resolution): must be a positive number of metres per pixel, "
                         f"got {resolution!r}")
    # -- obstacle models (issue 15): one name everywhere; `use` is its old name --
    from ..detection.obstacles import DEFAULT_OBSTACLE_MODEL, check_obstacle_model

    if use is not None and obstacle_model is not None and use != obstacle_model:
        raise MapFormatError(f"use: {use!r} contradicts obstacle_model {obstacle_model!r}")
    model = obstacle_model or use or DEFAULT_OBSTACLE_MODEL
    try:
        check_obstacle_model(model)
    except InputError as exc:
        raise MapFormatError(str(exc)) from None
    explicit = (obstacle_model or use) is not None
    p = Path(path)
    if not p.exists():
        raise MapFormatError(f"{p}: no such file")
    if p.is_dir():
        raise MapFormatError(f"{p}: is a folder, not an obstacle file")
    if not p.is_file():
        raise MapFormatError(f"{p}: is not a regular file (a device, FIFO or socket)")
    ext = p.suffix.lower()
    if ext in (".json", ".geojson"):
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise MapFormatError(f"{p}: not valid JSON ({exc})") from None
        except RecursionError:
            raise MapFormatError(f"{p}: not an obstacle file (nested too deeply)") from None
        if isinstance(data, dict) and data.get("type") == "FeatureCollection":
            return _from_geojson(data, str(p), model if explicit else None)
        if isinstance(data, dict) and str(data.get("format", "")).startswith("sbplan.detection"):
            return detection_obstacles(data, use=model, source=str(p))
        raise MapFormatError(f"{p}: neither a GeoJSON FeatureCollection nor an sbplan detection result")
    if ext in (".yaml", ".yml"):
        return _from_nav2(p, image_anywhere=image_anywhere)
    _refuse_non_map(p)
    try:
        img = load_image(p)
    except ImageError as exc:
        raise MapFormatError(str(exc)) from None
    res = 1.0 if resolution is None else float(resolution)
    if not math.isfinite(res) or res <= 0:
        raise MapFormatError(f"resolution: must be > 0, got {resolution!r}")
    occ = img < 128
    return ObstacleSet(occupancy_polygons(occ, resolution=res, source=str(p)),
                       (0.0, 0.0, img.shape[1] * res, img.shape[0] * res), str(p))


def _refuse_non_map(p: Path) -> None:
    """Images sbplan writes that are not maps of the floor say so in their metadata
    (:func:`sbplan.imageio.image_text`): refuse them, naming the file to plan on instead."""
    kind = image_text(p).get("sbplan")
    if kind == "camera-occupancy":
        raise MapFormatError(
            f"{p}: the occupancy image of 'sbplan detect' is in the camera's pixels, not a map of the floor; "
            "plan on the detection result (sbplan detect -o result.json), its --geojson or its --nav2 map.yaml")
    if kind == "overlay":
        raise MapFormatError(f"{p}: the overlay picture of 'sbplan detect' is not a map; plan on the detection "
                             "result (sbplan detect -o result.json), its --geojson or its --nav2 map.yaml")
    if kind == "nav2-map":
        raise MapFormatError(f"{p}: the image of a nav2 map; plan on {p.with_name('map.yaml')}, which gives its "
                             "resolution and origin")


def _bounds(b: Any, where: str) -> tuple | None:
    if b is None:
        return None
    try:
        t = tuple(float(v) for v in b)
    except (TypeError, ValueError):
        raise MapFormatError(f"{where}: bounds_m must be [xmin, ymin, xmax, ymax]") from None
    if len(t) != 4 or not all(math.isfinite(v) for v in t) or t[0] >= t[2] or t[1] >= t[3]:
        raise MapFormatError(f"{where}: bounds_m must be [xmin, ymin, xmax, ymax] with min < max")
    return t


def _poly(coords: Any, where: str) -> Polygon:
    try:
        a = np.asarray(coords, dtype=float)
    except (TypeError, ValueError):
        raise MapFormatError(f"{where}: polygon coordinates are not numbers") from None
    if a.ndim != 2 or a.shape[1] != 2 or len(a) < 3 or not np.isfinite(a).all():
        raise MapFormatError(f"{where}: expected at least 3 finite [x, y] points")
    return Polygon(a)


def detection_obstacles(detection: Detection | dict[str, Any], *, use: str | None = None, source: str = "") -> ObstacleSet:
    """The obstacles of a detection result, as the planner takes them: the one place that says
    which polygons of a detection are obstacles (``sbplan demo``, the TUI and
    :func:`load_obstacles` all come here).

    Parameters
    ----------
    detection : Detection or dict
        A :class:`sbplan.Detection`, or its JSON form (``Detection.to_json()``, the content of a
        ``result.json``, whose coordinates are rounded to 1e-6 m).
    use : "mar" | "parts" | "outline"
        The obstacle model (:mod:`sbplan.detection.obstacles`): each obstacle's minimum-area
        rectangle (``mar_m``), the rectangles of its parts (``parts_m``, the default) or its
        outline (``outline_m``).
    source : str
        Where the detection came from, for messages and ``ObstacleSet.source``.

    Returns
    -------
    ObstacleSet
        The polygons in metres (world frame, y up) and the bounds of the calibrated grid.
    """
    from ..detection.obstacles import DEFAULT_OBSTACLE_MODEL, OBSTACLE_MODELS, json_polygons_m

    use = DEFAULT_OBSTACLE_MODEL if use is None else use
    if use not in OBSTACLE_MODELS:
        raise MapFormatError(f"use: expected one of {', '.join(OBSTACLE_MODELS)}, got {use!r}")
    src = source or "detection"
    if not isinstance(detection, dict):
        obstacles = getattr(detection, "obstacles", None)
        calibration = getattr(detection, "calibration", None)
        if obstacles is None or calibration is None or not hasattr(detection, "planner_obstacles"):
            raise InputError(f"detection: expected a Detection or its JSON, got {type(detection).__name__}")
        try:
            polys = [Polygon(p) for p in detection.planner_obstacles(use)]
        except InputError as exc:
            raise InputError(f"{src}: {exc}") from None
        return ObstacleSet(polys, tuple(float(v) for v in calibration.world_bounds()), source)
    obs = detection.get("obstacles")
    if not isinstance(obs, list):
        raise MapFormatError(f"{src}: 'obstacles' must be a list")
    polys = []
    for i, ob in enumerate(obs):
        try:
            rings = json_polygons_m(ob, use)
        except (KeyError, TypeError):
            key = {"mar": "'mar_m'", "parts": "'parts_m' (nor 'outline_m' to cut parts from)",
                   "outline": "'outline_m'"}[use]
            raise MapFormatError(f"{src}: obstacles[{i}] has no {key}") from None
        except (ValueError, InputError) as exc:
            raise MapFormatError(f"{src}: obstacles[{i}]: {exc}") from None
        polys += [_poly(r, f"{src}: obstacles[{i}] ({use})") for r in rings]
    ws = detection.get("workspace") or {}
    return ObstacleSet(polys, _bounds(ws.get("bounds_m") if isinstance(ws, dict) else None, src), source)


def _from_geojson(data: dict, src: str, model: str | None = None) -> ObstacleSet:
    feats = data.get("features")
    if not isinstance(feats, list):
        raise MapFormatError(f"{src}: 'features' must be a list")
    items = []
    for i, f in enumerate(feats):
        geom = f.get("geometry") if isinstance(f, dict) else None
        if not isinstance(geom, dict):
            raise MapFormatError(f"{src}: features[{i}] has no geometry")
        props = f.get("properties") or {}
        kind = props.get("kind") if isinstance(props, dict) else None
        if kind is not None and not isinstance(kind, str):
            raise MapFormatError(f"{src}: features[{i}].properties.kind must be a string")
        t = geom.get("type")
        if t == "Polygon":
            parts = [geom.get("coordinates")]
        elif t == "MultiPolygon":
            parts = geom.get("coordinates") or []
        else:
            raise MapFormatError(f"{src}: features[{i}] is a {t}, expected Polygon or MultiPolygon")
        for rings in parts:
            if not isinstance(rings, list) or not rings:
                raise MapFormatError(f"{src}: features[{i}] has no polygon rings")
            shell = _poly(rings[0], f"{src}: features[{i}]")
            holes = [_poly(r, f"{src}: features[{i}] hole").exterior.coords for r in rings[1:]]
            items.append((kind, Polygon(shell.exterior.coords, holes)))
    found = data.get("sbplan")
    meta: dict = found if isinstance(found, dict) else {}
    # the features of the obstacle model asked for, else of the one the file was written with
    # (files written before the models: their MARs)
    from ..detection.exports import GEOJSON_KINDS

    asked = model
    model = model or meta.get("obstacle_model") or "mar"
    want = GEOJSON_KINDS.get(model, "mar")
    kinds = {k for k, _ in items if k is not None}
    polys = [p for k, p in items if k == want] if kinds else [p for _, p in items]
    if kinds and not polys:
        if asked is not None:
            raise MapFormatError(f"{src}: no {want!r} features for the {asked!r} obstacle model "
                                 f"(the file holds {', '.join(sorted(kinds))})")
        polys = [p for _, p in items]
    if meta.get("georeference") is not None:
        # WGS84 lon/lat written by sbplan detect on a georeferenced floor: back to the floor's metres
        geo = Georeference.from_json(meta["georeference"], where=f"{src}: sbplan.georeference")
        polys = [shapely.transform(q, geo.to_world) for q in polys]
    return ObstacleSet(polys, _bounds(meta.get("bounds_m"), src), src)


def _read_yaml(p: Path) -> dict:
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8", errors="replace"))
    except (yaml.YAMLError, ValueError, RecursionError) as exc:
        text = " ".join(str(exc).split())
        raise MapFormatError(f"{p}: not valid YAML ({text[:160]})") from None
    if not isinstance(data, dict):
        raise MapFormatError(f"{p}: not a nav2 map.yaml (expected a mapping)")
    return data


#: map_server's OccupancyGrid values: free, occupied, unknown.
FREE, OCCUPIED, UNKNOWN = 0, 100, -1


def map_server_values(image: np.ndarray, *, mode: str = "trinary", negate: bool = False,
                      occupied_thresh: float = 0.65, free_thresh: float = 0.196) -> np.ndarray:
    """The occupancy values ROS 2 nav2's ``map_server`` loads from a map image.

    As ``nav2_map_server``'s ``loadMapFromFile``: a pixel's shade is the mean of its colour
    channels over the channel range (with the alpha channel averaged in, in trinary mode), its
    occupancy ``occ`` is ``shade`` with ``negate``, else ``1 - shade``; then

    - ``trinary``: 100 where ``occ > occupied_thresh``, 0 where ``occ < free_thresh``, else -1;
    - ``scale``: -1 where the pixel is not opaque, else as trinary but the values between the
      thresholds are scaled linearly to 0..100;
    - ``raw``: the pixel value itself (``round(shade * 255)``, ``negate`` ignored) where it is
      0..100, else -1.

    Parameters
    ----------
    image : ndarray of shape (H, W), (H, W, 3) or (H, W, 4)
        uint8 or uint16, as decoded (colour in OpenCV's BGR(A) order); row 0 is the map's top.
    mode : "trinary" | "scale" | "raw"
    negate : bool
    occupied_thresh, free_thresh : float, 0 <= free_thresh < occupied_thresh <= 1

    Returns
    -------
    ndarray of shape (H, W), int8, indexed ``(row, col)`` like the image: 0..100 or -1 (unknown).
    """
    if mode not in ("trinary", "scale", "raw"):
        raise MapFormatError(f"mode: expected trinary, scale or raw, got {mode!r}")
    if not (0.0 <= free_thresh < occupied_thresh <= 1.0):
        raise MapFormatError(f"free_thresh, occupied_thresh: need 0 <= free_thresh < occupied_thresh <= 1, "
                             f"got {free_thresh!r}, {occupied_thresh!r}")
    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16) or img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (1, 3, 4)):
        raise MapFormatError(f"image: expected an 8- or 16-bit grey, colour or colour+alpha image, got "
                             f"{img.dtype} of shape {img.shape}")
    top = float(np.iinfo(img.dtype).max)
    planes = img.astype(np.float64).reshape(img.shape[0], img.shape[1], -1) / top
    colour, alpha = (planes[..., :3], planes[..., 3]) if planes.shape[2] == 4 else (planes, None)
    if alpha is not None and mode == "trinary":
        shade = np.concatenate([colour, alpha[..., None]], axis=2).mean(axis=2)
    else:
        shade = colour.mean(axis=2)
    if mode == "raw":
        value = np.rint(shade * 255.0)
        return np.where(value <= OCCUPIED, value, UNKNOWN).astype(np.int8)
    occ = shade if negate else 1.0 - shade
    out = np.full(occ.shape, UNKNOWN, np.int8)
    out[occ > occupied_thresh] = OCCUPIED
    out[occ < free_thresh] = FREE
    if mode == "scale":
        between = (occ >= free_thresh) & (occ <= occupied_thresh)
        out[between] = np.rint((occ[between] - free_thresh) / (occupied_thresh - free_thresh) * 100.0)
        if alpha is not None:
            out[alpha < 1.0] = UNKNOWN
    return out


def _nav2_number(p: Path, data: dict, key: str, default: Any = None) -> float:
    v = data.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise MapFormatError(f"{p}: {key} must be a finite number, got {v!r}")
    return float(v)


def _from_nav2(p: Path, *, image_anywhere: bool = False) -> ObstacleSet:
    """A nav2 map: the cells map_server does not load as free (:func:`map_server_values`:
    occupied, unknown, or a value in between) are the obstacles."""
    data = _read_yaml(p)
    if not {"image", "resolution", "origin"} & set(map(str, data)):
        raise MapFormatError(f"{p}: not a nav2 map.yaml (none of the keys image, resolution, origin)")
    for k in ("image", "resolution", "origin"):
        if k not in data:
            raise MapFormatError(f"{p}: nav2 map.yaml lacks {k!r}")
    res = _nav2_number(p, data, "resolution")
    if res <= 0:
        raise MapFormatError(f"{p}: resolution must be > 0 metres per pixel, got {res:g}")
    origin_raw = data["origin"]
    if not isinstance(origin_raw, list) or not 2 <= len(origin_raw) <= 3:
        raise MapFormatError(f"{p}: origin must be [x, y, yaw], got {origin_raw!r}")
    origin = [_nav2_number(p, {"origin": v}, "origin") for v in origin_raw]
    yaw = origin[2] if len(origin) > 2 else 0.0
    negate = data.get("negate", 0)
    if isinstance(negate, str) or negate not in (0, 1):
        raise MapFormatError(f"{p}: negate must be 0 or 1, got {negate!r}")
    negate = int(negate)
    occ_t = _nav2_number(p, data, "occupied_thresh", 0.65)
    free_t = _nav2_number(p, data, "free_thresh", 0.196)
    if not 0.0 <= free_t < occ_t <= 1.0:
        raise MapFormatError(f"{p}: thresholds must satisfy 0 <= free_thresh < occupied_thresh <= 1, "
                             f"got free_thresh {free_t:g}, occupied_thresh {occ_t:g}")
    mode = data.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        raise MapFormatError(f"{p}: mode must be trinary, scale or raw, got {mode!r}")
    image = data["image"]
    if not isinstance(image, str) or not image.strip():
        raise MapFormatError(f"{p}: image must be a file name, got {image!r}")
    folder = p.parent.resolve()
    img_path = (folder / image).resolve()
    if not image_anywhere and folder not in img_path.parents:
        raise MapFormatError(f"{p}: image {image!r} lies outside the map's folder {folder}; move it beside "
                             "map.yaml (or allow it: --nav2-image-anywhere, image_anywhere=True)")
    try:
        img = read_image(img_path)
    except ImageError as exc:
        raise MapFormatError(str(exc)) from None
    try:
        values = map_server_values(img, mode=mode, negate=bool(negate), occupied_thresh=occ_t, free_thresh=free_t)
    except MapFormatError as exc:
        raise MapFormatError(f"{p}: {exc}") from None
    occupied = values != FREE
    h, w = occupied.shape
    if abs(yaw) <= 1e-9:
        polys = occupancy_polygons(occupied, resolution=res, origin=(origin[0], origin[1]), source=str(p))
        bounds = (origin[0], origin[1], origin[0] + w * res, origin[1] + h * res)
        return ObstacleSet(polys, bounds, str(p))
    polys, bounds = _rotated_map(occupied, res, origin[0], origin[1], yaw)
    return ObstacleSet(polys, bounds, str(p))


def _rotated_map(occupied: np.ndarray, res: float, ox: float, oy: float, yaw: float) -> tuple[list, tuple]:
    """A nav2 map whose origin pose has yaw != 0: the image's lower-left corner is at (ox, oy) and
    its x axis (columns) points at angle yaw, counter-clockwise. The occupied cells are rotated
    about the origin. The planner's workspace is an axis-aligned rectangle, so the bounds become
    the rotated image's bounding box and its parts outside the image count as obstacles (space
    the map says nothing about, like unknown cells): routes stay on the map, as with yaw 0."""
    c, s_ = math.cos(yaw), math.sin(yaw)
    m = [c, -s_, s_, c, ox, oy]  # shapely's affine [a, b, d, e, xoff, yoff]: x' = a x + b y + xoff
    h, w = occupied.shape
    polys = [shapely.affinity.affine_transform(q, m) for q in occupancy_polygons(occupied, resolution=res,
                                                                                  source="map")]
    extent = shapely.affinity.affine_transform(box(0.0, 0.0, w * res, h * res), m)
    x0, y0, x1, y1 = (float(v) for v in extent.bounds)
    bounds = (x0, y0, x1, y1)
    outside = box(x0, y0, x1, y1).difference(extent)
    # Drop the rounding slivers left where the image is (nearly) axis-aligned (yaw near k pi/2).
    tiny = 1e-9 * extent.area
    polys += [q for q in getattr(outside, "geoms", [outside]) if isinstance(q, Polygon) and q.area > tiny]
    return polys, bounds


def occupancy_polygons(occupied: np.ndarray, *, resolution: float = 1.0,
                       origin: tuple[float, float] = (0.0, 0.0), source: str = "occupancy image") -> list[Polygon]:
    """Occupied pixels as exact polygons (with holes): the union of :func:`occupancy_rectangles`,
    collinear vertices removed. Same frame and parameters as :func:`occupancy_rectangles`.

    Merged walls have fewer edges than their rectangles (the maze: 160 instead of 260), and no
    shared inner edges or T-junction vertices for the planner to test.

    Raises LimitError when the image has more runs of occupied pixels than the
    ``obstacle_vertices`` limit (:mod:`sbplan.limits`): merging them would take minutes (a noisy
    image, not a map).
    """
    occ = np.asarray(occupied, bool)
    runs = int(np.count_nonzero(np.diff(occ.astype(np.int8), axis=-1, prepend=0) == 1)) if occ.ndim else 0
    limits.check("obstacle_vertices", runs, f"{source}: {runs:,} runs of occupied pixels",
                 "is it noisy? clean it (a morphological opening) or give a coarser map")
    rects = occupancy_rectangles(occupied, resolution=resolution, origin=origin)
    if not rects:
        return []
    u = shapely.union_all(rects)
    # (simplify(0) drops collinear vertices: a polygon stays a polygon)
    return [cast(Polygon, g.simplify(0.0)) for g in getattr(u, "geoms", [u]) if isinstance(g, Polygon) and g.area > 0]


def occupancy_rectangles(occupied: np.ndarray, *, resolution: float = 1.0,
                         origin: tuple[float, float] = (0.0, 0.0)) -> list[Polygon]:
    """Exact decomposition of occupied pixels into axis-aligned rectangles.

    Runs of occupied pixels in each row are merged with identical runs in the rows below them.

    Parameters
    ----------
    occupied : ndarray of shape (H, W), bool, indexed ``(row, col)``; row 0 is the top.
    resolution : float, world units per pixel.
    origin : (x, y) of the image's bottom-left corner in the world.

    Returns
    -------
    list of shapely Polygon, world ``(x, y)``, y up: pixel (row, col) covers
    x in [ox + col*res, ox + (col+1)*res], y in [oy + (H-1-row)*res, oy + (H-row)*res].
    """
    occ = np.asarray(occupied, bool)
    if occ.ndim != 2:
        raise MapFormatError(f"occupied: expected a 2-D mask, got shape {occ.shape}")
    h, w = occ.shape
    pad = np.zeros((h, w + 2), np.int8)
    pad[:, 1:-1] = occ
    dif = np.diff(pad, axis=1)
    rs, cs = np.nonzero(dif == 1)
    re, ce = np.nonzero(dif == -1)  # same row order, runs [cs, ce)
    open_runs: dict[tuple[int, int], int] = {}  # (c0, c1) -> first row
    rects = []
    row_runs: dict[int, list] = {}
    for r, c0, c1 in zip(rs.tolist(), cs.tolist(), ce.tolist()):
        row_runs.setdefault(r, []).append((c0, c1))
    for r in range(h + 1):
        cur = set(row_runs.get(r, ()))
        for run in list(open_runs):
            if run not in cur:
                rects.append((open_runs.pop(run), r, run[0], run[1]))
        for run in cur:
            open_runs.setdefault(run, r)
    ox, oy = origin
    return [box(ox + c0 * resolution, oy + (h - r1) * resolution, ox + c1 * resolution, oy + (h - r0) * resolution)
            for r0, r1, c0, c1 in rects]
