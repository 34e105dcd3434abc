"""Files a user can open: overlay picture, occupancy image, GeoJSON, and a ROS 2 nav2 map.

All writers are atomic. World coordinates are metres, x right along the columns, y up (nav2's frame).

What you see is what is avoided: the overlay, the GeoJSON and the nav2 map show the polygons the
planner gets under the chosen obstacle model (:mod:`sbplan.detection.obstacles`), in the planner's
geometry (metres, through the grid), and the overlay adds their clearance as the planner enlarges
them by the robot's radius, clipped to the workspace: :func:`planner_view`.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import cv2
import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from .. import limits
from ..errors import InputError
from ..files import write_atomic, write_file_set
from ..imageio import as_gray, encode_image
from ..polygons import signed_area
from .obstacles import DEFAULT_OBSTACLE_MODEL, check_obstacle_model
from ..workspace import Georeference
from .result import Detection

#: nav2 map pixels (trinary mode, negate 0): what map_saver writes for occupied, free and unknown.
NAV2_OCCUPIED, NAV2_FREE, NAV2_UNKNOWN = 0, 254, 205

#: What the images that are not maps say of themselves (PNG text, PGM comment): ``sbplan plan``
#: refuses them with a message naming the files to plan on (sbplan.planning.loaders).
OCCUPANCY_NOTE = ("the occupancy image of sbplan detect: the camera's pixels (black = occupied cell), not a map "
                  "of the floor; plan on the detection result (-o result.json), the GeoJSON or the nav2 map.yaml")
OVERLAY_NOTE = "the overlay picture of sbplan detect: the camera's view with the detection drawn on it, not a map"
NAV2_IMAGE_NOTE = "the image of a nav2 map: map.yaml beside it gives its resolution and origin"

_RED, _GREEN, _YELLOW, _CYAN, _WHITE, _BLACK = (40, 40, 230), (60, 200, 60), (0, 220, 255), (230, 200, 0), (255, 255, 255), (0, 0, 0)
_ORANGE = (0, 140, 255)


def planner_view(detection: Detection, model: str = DEFAULT_OBSTACLE_MODEL, *, robot_radius: float | None = None,
                 margin: float = 0.0) -> tuple[list, list]:
    """What the planner gets from ``detection`` under ``model``: the obstacles' polygons and their
    clearance zones, shapely polygons in world metres.

    The polygons are :meth:`Detection.planner_obstacles` as the planner takes them
    (:class:`sbplan.planning.PlanningMap`'s ``obstacles``); the clearance zones are the planner's
    own enlargement of them by ``robot_radius + margin`` (``PlanningMap.enlarged``), clipped to the
    workspace bounds (the floor the grid covers), where the robot's centre stays.

    Parameters
    ----------
    detection : Detection
    model : "mar" | "parts" | "outline"
    robot_radius : float, optional
        Default: the calibration's workspace robot radius.
    margin : float
        Extra safety distance, as :func:`sbplan.plan` takes it.

    Returns
    -------
    (obstacles, clearance) : two lists of shapely Polygon
    """
    from ..planning import PlanningMap

    check_obstacle_model(model)
    cal = detection.calibration
    radius = cal.workspace.robot_radius_m if robot_radius is None else float(robot_radius)
    polygons = detection.planner_obstacles(model)
    if not polygons:
        return [], []
    bounds = cal.world_bounds()
    pmap = PlanningMap(polygons, robot_radius=radius, margin=margin, bounds=bounds)
    floor = shapely.box(*bounds)
    clearance = []
    for zone in pmap.enlarged:
        clipped = zone.intersection(floor)
        clearance += [g for g in getattr(clipped, "geoms", [clipped]) if g.geom_type == "Polygon" and g.area > 0]
    return list(pmap.obstacles), clearance


def overlay_polygons(detection: Detection, model: str = DEFAULT_OBSTACLE_MODEL, **planner: float) -> tuple[list, list]:
    """:func:`planner_view` drawn in the frame: the obstacles' and the clearance zones' outer rings
    as ``(K, 2)`` pixel arrays ``(x, y)`` of the frame the detection was made on (through the grid
    and the camera's movement). What :func:`overlay_image` draws."""
    obstacles, clearance = planner_view(detection, model, **planner)
    cal, cam = detection.calibration, detection.camera

    def ring(g) -> np.ndarray:
        px = cal.world_to_pixels(np.asarray(g.exterior.coords)[:-1])
        return cam.to_frame(px) if cam.moved else px

    return [ring(g) for g in obstacles], [ring(g) for g in clearance]


def overlay_image(image: np.ndarray, detection: Detection, model: str = DEFAULT_OBSTACLE_MODEL, *,
                  caption: bool = True, **planner: float) -> np.ndarray:
    """The scene with occupied cells shaded red, found symbols marked green, each obstacle's
    footprint outline (thin red), what the planner avoids under ``model`` (yellow) with its
    clearance (thin orange, :func:`overlay_polygons`), and obstacle numbers (as the paper's
    figure 12).

    The detection's pixel coordinates are the calibration's; they are drawn where the camera's
    movement (``detection.camera``) puts them in this frame.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, 3)
        The frame the detection was made on.
    detection : Detection
    model : "mar" | "parts" | "outline"
    caption : bool
        Add a caption band above the scene (symbols found, occupied cells, obstacles, the model),
        so that it hides none of the scene.
    **planner
        ``robot_radius``, ``margin`` as :func:`planner_view` takes them.

    Returns
    -------
    ndarray of shape (H + band, W, 3), uint8, BGR
        The scene's pixels are rows ``band:`` (``band`` is 0 without the caption).
    """
    gray = as_gray(image)
    out = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    grid = detection.calibration.grid
    cam = detection.camera
    to_frame = cam.to_frame if cam.moved else (lambda xy: np.asarray(xy, dtype=np.float64))
    corners = to_frame(grid.cell_corners_px())
    shade = out.copy()
    for r, c in detection.occupied_cells:
        quad = np.array([corners[r, c], corners[r, c + 1], corners[r + 1, c + 1], corners[r + 1, c]])
        cv2.fillPoly(shade, [np.rint(quad * 16).astype(np.int32)], _RED, lineType=cv2.LINE_AA, shift=4)
    out = cv2.addWeighted(shade, 0.35, out, 0.65, 0)
    scale = max(1, round(min(gray.shape) / 500))
    for x, y in to_frame(detection.matched_centres_px.reshape(-1, 2)):
        cv2.circle(out, (int(round(x)), int(round(y))), 3 * scale, _GREEN, -1, cv2.LINE_AA)
    for x, y in to_frame(detection.candidates_px.reshape(-1, 2)):
        cv2.drawMarker(out, (int(round(x)), int(round(y))), _CYAN, cv2.MARKER_TILTED_CROSS, 8 * scale, scale)
    has_world = all(ob.outline_m is not None for ob in detection.obstacles)
    if has_world:
        avoided, clearance = overlay_polygons(detection, model, **planner)
    else:  # no world frame: the model's pixel polygons, no clearance
        avoided, clearance = [to_frame(p) for ob in detection.obstacles for p in ob.polygons_px(model)], []
    for ob in detection.obstacles:
        cv2.polylines(out, [np.rint(to_frame(ob.outline_px) * 16).astype(np.int32)], True, _RED, scale,
                      cv2.LINE_AA, shift=4)
    for ring in clearance:
        cv2.polylines(out, [np.rint(ring * 16).astype(np.int32)], True, _ORANGE, scale, cv2.LINE_AA, shift=4)
    for ring in avoided:
        cv2.polylines(out, [np.rint(ring * 16).astype(np.int32)], True, _YELLOW, 2 * scale, cv2.LINE_AA, shift=4)
    for ob in detection.obstacles:
        label = str(ob.id)
        font, fs, th = cv2.FONT_HERSHEY_SIMPLEX, 0.9 * scale, 2 * scale
        (tw, tht), _ = cv2.getTextSize(label, font, fs, th)
        cx, cy = to_frame(np.asarray(ob.centre_px, dtype=np.float64))
        org = (int(cx - tw / 2), int(cy + tht / 2))
        cv2.putText(out, label, org, font, fs, _BLACK, th + 3 * scale, cv2.LINE_AA)
        cv2.putText(out, label, org, font, fs, _WHITE, th, cv2.LINE_AA)
    if not caption:
        return out
    rescued = f" (+{detection.symbols_rescued} by edge)" if detection.symbols_rescued else ""
    text = (f"{detection.symbols_found}/{detection.symbols_expected} symbols{rescued}, "
            f"{len(detection.occupied_cells)} occupied cells, {len(detection.obstacles)} obstacles ({model})")
    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.55 * scale, scale)
    # the caption gets its own band: drawn over the scene it hid the top row of symbols
    band = np.full((th + base + 10 * scale, out.shape[1], 3), 40, np.uint8)
    cv2.putText(band, text, (8 * scale, th + 5 * scale), cv2.FONT_HERSHEY_SIMPLEX, 0.55 * scale, _WHITE, scale,
                cv2.LINE_AA)
    return np.concatenate([band, out])


def encode_overlay(path: str | os.PathLike, image: np.ndarray, detection: Detection,
                   model: str = DEFAULT_OBSTACLE_MODEL, **planner: float) -> bytes:
    """The overlay picture (:func:`overlay_image`), in the camera's pixels, encoded for ``path``'s
    ending; a PNG or PGM says what it is in its metadata (``sbplan: overlay``)."""
    return encode_image(path, overlay_image(image, detection, model, caption=True, **planner),
                        text={"sbplan": "overlay", "Description": OVERLAY_NOTE})


def write_overlay(path: str | os.PathLike, image: np.ndarray, detection: Detection,
                  model: str = DEFAULT_OBSTACLE_MODEL, **planner: float) -> Path:
    """Write :func:`encode_overlay` atomically."""
    return write_atomic(path, encode_overlay(path, image, detection, model, **planner))


def encode_occupancy(path: str | os.PathLike, detection: Detection) -> bytes:
    """The occupancy image (paper figure 14): black occupied blocks on white, in the camera's
    pixels (the calibration's), encoded for ``path``'s ending. A PNG or PGM says what it is in its
    metadata (``sbplan: camera-occupancy``): ``sbplan plan`` refuses it as a map of the floor."""
    return encode_image(path, detection.occupancy, text={"sbplan": "camera-occupancy", "Description": OCCUPANCY_NOTE})


def write_occupancy(path: str | os.PathLike, detection: Detection) -> Path:
    """Write :func:`encode_occupancy` atomically."""
    return write_atomic(path, encode_occupancy(path, detection))


#: GeoJSON ``kind`` of the features that hold each obstacle model's polygons (the footprint's
#: outline is always written, as ``outline``).
GEOJSON_KINDS = {"mar": "mar", "parts": "part", "outline": "outline"}


def geojson(detection: Detection, model: str = DEFAULT_OBSTACLE_MODEL, *,
            georeference: Georeference | None = None) -> dict:
    """Obstacles as a GeoJSON FeatureCollection.

    Each obstacle gives its footprint's outline (``kind: "outline"``) and, unless the model is
    ``outline``, the polygons the planner avoids under ``model``: its MAR (``kind: "mar"``) or its
    parts (``kind: "part"``, one feature each, numbered by ``part``); exterior rings
    counter-clockwise (RFC 7946's right-hand rule).

    Coordinates are RFC 7946's WGS84 ``[longitude, latitude]`` in degrees (9 decimals, about
    0.1 mm) when the floor is georeferenced (``georeference``, by default the calibration's
    ``workspace.georeference``), else the local world frame's ``[x, y]`` in metres (x right along
    the grid's columns, y up toward row 0), which GIS tools read as degrees near (0, 0): they are
    for sbplan and programs that know the frame. The foreign member ``sbplan`` says which
    (``crs``: ``"WGS84"`` or ``"local"``), the georeference, the floor's bounds in metres and
    ``obstacle_model``, which tells a reader (:func:`sbplan.planning.load_obstacles`) which
    features to plan around.
    """
    check_obstacle_model(model)
    geo = georeference if georeference is not None else detection.calibration.workspace.georeference
    features = []

    def feature(ring, props) -> dict:
        ring = np.asarray(ring, np.float64)
        if geo is not None:
            ring, digits = geo.to_lonlat(ring), 9
        else:
            digits = 6
        # RFC 7946: exterior rings counter-clockwise with y (latitude) up, which is clockwise
        # in polygons.signed_area's y-down convention; first point repeated
        if signed_area(ring) > 0:
            ring = ring[::-1]
        coords = np.vstack([ring, ring[:1]]).round(digits).tolist()
        return {"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [coords]}, "properties": props}

    for ob in detection.obstacles:
        cells = [list(c) for c in ob.cells]
        features.append(feature(ob.outline_m, {"id": ob.id, "kind": "outline", "cells": cells}))
        if model == "outline":
            continue
        for k, ring in enumerate(ob.polygons_m(model)):
            props = {"id": ob.id, "kind": GEOJSON_KINDS[model], "cells": cells}
            if model == "parts":
                props["part"] = k
            features.append(feature(ring, props))
    meta: dict = {"bounds_m": [round(v, 6) for v in detection.calibration.world_bounds()], "obstacle_model": model}
    if geo is not None:
        meta = {"crs": "WGS84", "coordinates": "[longitude, latitude] in degrees (RFC 7946)",
                "georeference": geo.to_json(), **meta}
    else:
        meta = {"crs": "local", "coordinates": "[x, y] in metres of the local frame, not longitude and latitude",
                "frame": "local metric frame: metres, x right along the grid's columns, y up toward row 0", **meta}
    return {"type": "FeatureCollection", "features": features, "sbplan": meta}


def write_geojson(path: str | os.PathLike, detection: Detection, model: str = DEFAULT_OBSTACLE_MODEL, *,
                  georeference: Georeference | None = None) -> Path:
    """Write :func:`geojson` atomically."""
    return write_atomic(path, json.dumps(geojson(detection, model, georeference=georeference), indent=1) + "\n")


#: What a nav2 map folder written by :func:`write_nav2` holds.
NAV2_FILES = ("map.yaml", "map.pgm")


def nav2_resolution(resolution: float | None, pitch_m: tuple[float, float]) -> float:
    """The nav2 map's metres per pixel: ``resolution`` checked (finite, > 0), or a tenth of the
    smaller pitch. Raises InputError naming ``--nav2-resolution``."""
    if resolution is None:
        return min(pitch_m) / 10.0
    try:
        res = float(resolution)
    except (TypeError, ValueError):
        raise InputError(f"nav2 resolution (--nav2-resolution): expected metres per pixel, "
                         f"got {resolution!r}") from None
    if not (math.isfinite(res) and res > 0):
        raise InputError(f"nav2 resolution (--nav2-resolution): must be a positive number of metres per pixel, "
                         f"got {resolution!r}")
    return res


def nav2_pixels(polygons: list, *, shape: tuple[int, int], resolution: float,
                origin: tuple[float, float]) -> np.ndarray:
    """The map pixels that share area with any of ``polygons``: a (H, W) bool mask, row 0 at the top.

    A rasterisation that never loses part of an obstacle and adds no pixel an obstacle does not
    reach into: pixel ``(row, col)`` covers x in ``[ox + col*res, ox + (col+1)*res]`` and y in
    ``[oy + (H-1-row)*res, oy + (H-row)*res]`` (as :func:`sbplan.planning.occupancy_rectangles`
    reads it back), and is set when its overlap with a polygon exceeds 1e-6 of its area. Centre
    sampling (``cv2.fillPoly``) would drop the pixels an edge only clips, and growing the polygon
    by half a pixel's diagonal first (to keep them) also sets pixels the polygon merely touches at
    a corner, up to 1.7 pixels from it: on paper-8x6 that moved the goal inside the robot's
    clearance of an obstacle and made a route planned on the map approximate and 6 % longer.

    Parameters
    ----------
    polygons : list of (K, 2) arrays, world (x, y), y up
    shape : (H, W)
    resolution : float, world units per pixel
    origin : (x, y) of the map's bottom-left corner
    """
    h, w = shape
    ox, oy = origin
    occupied = np.zeros((h, w), bool)
    for p in polygons:
        ring = np.asarray(p, np.float64)
        poly: BaseGeometry = shapely.Polygon(ring)
        if not poly.is_valid:  # a self-touching outline: its area as the planner's union sees it
            poly = shapely.make_valid(poly)
        if not (poly.area > 0):
            continue
        # world -> pixel coordinates whose centres are integers, row 0 at the top edge y = oy + h * res
        q = np.column_stack([(ring[:, 0] - ox) / resolution - 0.5, h - (ring[:, 1] - oy) / resolution - 0.5])
        c0, r0 = np.maximum(np.floor(q.min(axis=0)).astype(int) - 1, 0)
        c1, r1 = np.minimum(np.ceil(q.max(axis=0)).astype(int) + 2, (w, h))
        if c0 >= c1 or r0 >= r1:
            continue
        q = q - (c0, r0)
        # Pixels the outline does not cross lie wholly inside or outside it: their centre decides.
        mine = np.zeros((r1 - r0, c1 - c0), np.uint8)
        cv2.fillPoly(mine, [np.rint(q * 256).astype(np.int32)], 1, cv2.LINE_8, shift=8)
        # Pixels it crosses lie within one pixel of points sampled along it at most a pixel
        # apart; their share of the polygon decides.
        closed = np.vstack([q, q[:1]])
        steps = [a + np.linspace(0.0, 1.0, int(np.ceil(np.hypot(*(b - a)))) + 2)[:, None] * (b - a)
                 for a, b in zip(closed[:-1], closed[1:])]
        pts = np.rint(np.vstack(steps)).astype(np.int64)
        crossed = np.zeros_like(mine)
        crossed[np.clip(pts[:, 1], 0, r1 - r0 - 1), np.clip(pts[:, 0], 0, c1 - c0 - 1)] = 1
        crossed = cv2.dilate(crossed, np.ones((3, 3), np.uint8))
        rows, cols = np.nonzero(crossed)
        xs, ys = ox + (cols + c0) * resolution, oy + (h - 1 - (rows + r0)) * resolution
        squares = shapely.box(xs, ys, xs + resolution, ys + resolution)
        shapely.prepare(poly)
        overlap = np.zeros(len(squares))
        near = shapely.intersects(poly, squares)
        overlap[near] = shapely.area(shapely.intersection(squares[near], poly))
        mine[rows, cols] = overlap > 1e-6 * resolution * resolution
        occupied[r0:r1, c0:c1] |= mine.astype(bool)
    return occupied


def nav2_map(detection: Detection, *, resolution: float | None = None,
             model: str = DEFAULT_OBSTACLE_MODEL) -> tuple[np.ndarray, dict]:
    """A ROS 2 nav2 ``map_server`` map of the floor: (image (H, W) uint8, yaml fields).

    The polygons the planner avoids under ``model`` are drawn in metres (the grid is regular in
    the world frame): a pixel is occupied when its square and a polygon share some area (more than
    1e-6 of the pixel's: a sliver that thin is float rounding on a pixel edge). So the map holds
    every polygon, grows none by more than the pixels its edges cross, and holds a polygon whose
    edges lie on pixel edges (the ``cells`` footprint's outlines at the default resolution)
    exactly: :func:`nav2_pixels`. Pixel 0 = occupied, 254 = free, 205 = unknown: the pixels of the
    last column and the top row that reach beyond the floor when ``resolution`` does not divide its
    size (the map says nothing about what lies there). Row 0 of the image is the top (largest y),
    as map_server expects; ``origin`` is the world pose of the bottom-left pixel's corner.
    ``free_thresh`` is 0.196 (map_server's classic value), below 205's occupancy (50/255 =
    0.1961), so map_server loads 205 as unknown (with nav2 map_saver's 0.25 it would load as free).

    Raises
    ------
    InputError
        ``resolution`` is not a positive finite number.
    LimitError
        The map would have more pixels than the ``map_pixels`` limit (:mod:`sbplan.limits`).
    """
    check_obstacle_model(model)
    cal = detection.calibration
    xmin, ymin, xmax, ymax = cal.world_bounds()
    res = nav2_resolution(resolution, cal.workspace.pitch_m)
    fw, fh = np.ceil((xmax - xmin) / res - 1e-9), np.ceil((ymax - ymin) / res - 1e-9)
    limits.check("map_pixels", float(fw) * float(fh),
                 f"a nav2 map of {fw:.0f} x {fh:.0f} pixels at {res:g} m per pixel", "give a coarser --nav2-resolution")
    width, height = int(fw), int(fh)
    image = np.full((height, width), NAV2_UNKNOWN, np.uint8)
    # free: the pixels wholly on the floor (to a billionth of its size: floating-point rounding)
    eps = 1e-9 * max(xmax - xmin, ymax - ymin)
    cols_in = int(np.sum(xmin + (np.arange(width) + 1) * res <= xmax + eps))
    rows_in = int(np.sum(ymin + (np.arange(height) + 1) * res <= ymax + eps))
    image[height - rows_in:, :cols_in] = NAV2_FREE
    occupied = nav2_pixels(detection.planner_obstacles(model), shape=(height, width), resolution=res,
                           origin=(xmin, ymin))
    image[occupied] = NAV2_OCCUPIED
    meta = {"image": "map.pgm", "mode": "trinary", "resolution": float(res),
            "origin": [float(xmin), float(ymin), 0.0], "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196, "obstacle_model": model}
    return image, meta


def nav2_files(detection: Detection, *, resolution: float | None = None,
               model: str = DEFAULT_OBSTACLE_MODEL) -> dict[str, bytes | str]:
    """The nav2 map's files, ``{"map.yaml": text, "map.pgm": bytes}`` (see :func:`nav2_map`)."""
    image, meta = nav2_map(detection, resolution=resolution, model=model)
    return {"map.yaml": nav2_yaml(meta), meta["image"]: encode_nav2_image(meta["image"], image)}


def encode_nav2_image(name: str, image: np.ndarray) -> bytes:
    """A nav2 map's image (:func:`nav2_map`) encoded for ``name``'s ending; a PNG or PGM says what
    it is in its metadata (``sbplan: nav2-map``): ``sbplan plan`` refuses it without its map.yaml."""
    return encode_image(name, image, text={"sbplan": "nav2-map", "Description": NAV2_IMAGE_NOTE})


def nav2_yaml(meta: dict) -> str:
    """The text of ``map.yaml`` for :func:`nav2_map`'s fields."""
    lines = [f"image: {meta['image']}", f"mode: {meta['mode']}", f"resolution: {meta['resolution']:.6g}",
             "origin: [{:.6g}, {:.6g}, {:.6g}]".format(*meta["origin"]), f"negate: {meta['negate']}",
             f"occupied_thresh: {meta['occupied_thresh']}", f"free_thresh: {meta['free_thresh']}"]
    if "obstacle_model" in meta:
        lines.append(f"# sbplan obstacle model: {meta['obstacle_model']}")
    return "\n".join(lines) + "\n"


def write_nav2(folder: str | os.PathLike, detection: Detection, *, resolution: float | None = None,
               model: str = DEFAULT_OBSTACLE_MODEL) -> Path:
    """Write ``map.yaml`` and ``map.pgm`` into ``folder`` as one unit (:func:`sbplan.files.write_file_set`:
    a reader sees the old pair or the new one, never a mix); returns the YAML's path.

    ``folder`` may hold only those two files: sbplan replaces the whole folder."""
    folder = write_file_set(folder, nav2_files(detection, resolution=resolution, model=model), names=NAV2_FILES)
    return folder / "map.yaml"
