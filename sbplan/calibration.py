"""Calibration on the empty floor (paper section 2.2).

From the reference image: every contour, the length filter, polygon approximation, descriptors and
centres of area; the reference symbol (given as an image of one symbol, or inferred as the dominant
repeated shape); the grid fitted to the symbols' centres; and a match threshold derived from the
data — the distances of the true symbols against those of every other contour — instead of the
paper's a-priori 0.5.
"""

from __future__ import annotations

import base64
import binascii
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from . import plugins
from .errors import CalibrationError, InputError
from .registration import THUMBNAIL_FACTOR, apply, centre_window, grey_centres, thumbnail
from .grid import Grid, fit_grid
from .imageio import as_gray, load_image, write_json
from .outline_check import (edge_contrast, edge_probes, inner_deviations, inner_tolerance, outline_deviation,
                            reference_samples, signed_distance_map)
from .workspace import Workspace, load_workspace

FORMAT = "sbplan.calibration/1"

#: The stages used when none is named: the fast ones (the paper's OKE and KKA are selectable).
DEFAULT_STAGES = {
    "binarizer": "background",
    "extractor": "opencv",
    "approximator": "douglas-peucker",
    "matcher": "fourier",
    "mapper": "cells",
}


@dataclass(frozen=True, eq=False)
class Calibration:
    """Everything detection needs, fitted on a reference image.

    Attributes
    ----------
    image_shape : (H, W)
    stages : dict
        kind -> ``{"name": ..., "options": {...}}`` for binarizer, extractor, approximator, matcher
        and mapper.
    grid : Grid
    symbol_polygons : list of ndarray (K, 2)
        The approximated outline of every cell's symbol in the reference, row-major.
    other_polygons : list of ndarray (K, 2)
        A sample of the reference's contours that are not symbols (for re-deriving thresholds).
    degraded_polygons : list of ndarray (K, 2)
        A sample of the symbols as found in degraded copies of the reference (likewise).
    descriptor : ndarray (K,)
        The reference symbol's descriptor under ``stages["matcher"]``.
    threshold : float
        A contour matches when its descriptor distance is below this.
    margin : float
        Nearest non-symbol distance divided by the farthest symbol distance (> 1 separates).
    symbol_area_px, symbol_points_range : float, (int, int)
        Median symbol area, and the range of contour lengths (boundary pixels) kept by the length
        filter during detection.
    outline_tolerance_px : float
        How far a matched symbol's outline may stray from its cell's reference outline, beyond a
        common shift, before the symbol counts as partly hidden (see :mod:`sbplan.outline_check`).
    inner_tolerance_px : ndarray (rows * cols, S) or None
        The other direction: per cell and point of its reference outline (S arc-length samples),
        how far that point may lie outside a found outline, beyond the common shift, as the
        degraded copies showed (:func:`sbplan.outline_check.inner_tolerance`). None in calibration
        files written before it existed: detection then uses ``outline_tolerance_px`` everywhere.
    edge_contrast : ndarray (rows * cols, EDGE_SAMPLES) or None
        Per cell and point of its reference outline, the relative step from ink to floor the
        reference shows across it (:func:`sbplan.outline_check.edge_contrast`): detection calls a
        symbol whole that the outline checks failed when its outline still shows a good part of
        this step everywhere. None in calibration files written before it existed (no such rescue).
    registration_centres_px : ndarray (rows, cols, 2) or None
        Every cell's symbol's grey-level centre in the reference
        (:func:`sbplan.registration.grey_centres`), what frames' symbols are compared with to
        register them to sub-pixel accuracy. None in older files: the grid's centres are used.
    reference_thumbnail : ndarray (H / 4, W / 4), uint8, or None
        The reference image made 4 times smaller (:func:`sbplan.registration.thumbnail`): its
        floor texture tells apart camera movements a whole pitch apart. None in older files.
    workspace : Workspace
    """

    image_shape: tuple[int, int]
    stages: dict[str, dict[str, Any]]
    grid: Grid
    symbol_polygons: list[np.ndarray]
    other_polygons: list[np.ndarray]
    degraded_polygons: list[np.ndarray]
    descriptor: np.ndarray
    threshold: float
    margin: float
    symbol_area_px: float
    symbol_points_range: tuple[int, int]
    outline_tolerance_px: float = 3.0
    inner_tolerance_px: np.ndarray | None = None
    edge_contrast: np.ndarray | None = None
    registration_centres_px: np.ndarray | None = None
    reference_thumbnail: np.ndarray | None = None
    workspace: Workspace = field(default_factory=Workspace)
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def symbols_expected(self) -> int:
        return self.grid.rows * self.grid.cols

    def stage(self, kind: str, override: Any = None):
        """The stage instance of ``kind``: ``override`` (a name or an instance) or the calibrated one."""
        if override is not None:
            return plugins.registry().create(kind, override)
        spec = self.stages[kind]
        return plugins.registry().create(kind, spec["name"], **spec.get("options", {}))

    def pixels_to_world(self, xy: np.ndarray) -> np.ndarray:
        """Image pixels ``(x, y)`` (N, 2) -> world metres ``(x, y)`` (N, 2), through the grid."""
        lattice = self.grid.px_to_lattice(xy)
        return self.workspace.lattice_to_world(lattice, self.grid.rows)

    def moved(self, matrix: np.ndarray) -> "Calibration":
        """This calibration for a camera moved by ``matrix`` (3x3, old pixels -> new pixels): every
        pixel geometry moved (grid, outlines, registration centres, thumbnail); what was measured
        along the outlines (tolerances, edge contrast) and the match threshold stay."""
        matrix = np.asarray(matrix, dtype=np.float64)
        grid = self.grid
        moved_grid = Grid(grid.rows, grid.cols, apply(matrix, grid.centres_px), matrix @ grid.homography,
                          grid.tolerance_px)
        thumb = self.reference_thumbnail
        if thumb is not None:
            f = np.diag([1.0 / THUMBNAIL_FACTOR, 1.0 / THUMBNAIL_FACTOR, 1.0])
            thumb = cv2.warpPerspective(thumb, f @ matrix @ np.linalg.inv(f), (thumb.shape[1], thumb.shape[0]),
                                        flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return replace(
            self, grid=moved_grid,
            symbol_polygons=[apply(matrix, p) for p in self.symbol_polygons],
            other_polygons=[apply(matrix, p) for p in self.other_polygons],
            degraded_polygons=[apply(matrix, p) for p in self.degraded_polygons],
            registration_centres_px=(None if self.registration_centres_px is None
                                     else apply(matrix, self.registration_centres_px)),
            reference_thumbnail=thumb)

    def world_bounds(self) -> tuple[float, float, float, float]:
        """The floor covered by the grid's cells, in metres: (xmin, ymin, xmax, ymax)."""
        corners = np.array([[-0.5, -0.5], [self.grid.cols - 0.5, -0.5],
                            [self.grid.cols - 0.5, self.grid.rows - 0.5], [-0.5, self.grid.rows - 0.5]])
        w = self.workspace.lattice_to_world(corners, self.grid.rows)
        return float(w[:, 0].min()), float(w[:, 1].min()), float(w[:, 0].max()), float(w[:, 1].max())

    # -- files --------------------------------------------------------------------------------
    def to_json(self) -> dict:
        return {
            "format": FORMAT,
            "image_shape": list(self.image_shape),
            "stages": self.stages,
            "grid": self.grid.to_json(),
            "symbol": {
                "descriptor": self.descriptor.tolist(),
                "threshold": self.threshold,
                "margin": self.margin,
                "area_px": self.symbol_area_px,
                "points_range": list(self.symbol_points_range),
                "outline_tolerance_px": self.outline_tolerance_px,
                **({} if self.inner_tolerance_px is None else
                   {"inner_tolerance_px": np.round(self.inner_tolerance_px, 3).tolist()}),
                **({} if self.edge_contrast is None else
                   {"edge_contrast": np.round(self.edge_contrast, 3).tolist()}),
                **({} if self.registration_centres_px is None else
                   {"registration_centres_px": np.round(self.registration_centres_px, 4).tolist()}),
                **({} if self.reference_thumbnail is None else
                   {"reference_thumbnail_png": _png_base64(self.reference_thumbnail)}),
                "polygons": [np.round(p, 3).tolist() for p in self.symbol_polygons],
            },
            "other_polygons": [np.round(p, 3).tolist() for p in self.other_polygons],
            "degraded_polygons": [np.round(p, 3).tolist() for p in self.degraded_polygons],
            "workspace": self.workspace.to_json(),
            "stats": self.stats,
        }

    @classmethod
    def from_json(cls, data: Any, *, source: str = "calibration") -> "Calibration":
        if not isinstance(data, dict) or "format" not in data:
            raise CalibrationError(f"{source}: not an sbplan calibration file")
        if data["format"] != FORMAT:
            raise CalibrationError(
                f"{source}: calibration format {data['format']!r} is not supported (expected {FORMAT!r}); "
                "re-run 'sbplan calibrate' on the reference image")
        try:
            sym = data["symbol"]
            return cls(
                image_shape=(int(data["image_shape"][0]), int(data["image_shape"][1])),
                stages={k: dict(v) for k, v in data["stages"].items()},
                grid=Grid.from_json(data["grid"]),
                symbol_polygons=[np.asarray(p, np.float64) for p in sym["polygons"]],
                other_polygons=[np.asarray(p, np.float64) for p in data["other_polygons"]],
                degraded_polygons=[np.asarray(p, np.float64) for p in data["degraded_polygons"]],
                descriptor=np.asarray(sym["descriptor"], np.float64),
                threshold=float(sym["threshold"]),
                margin=float(sym["margin"]),
                symbol_area_px=float(sym["area_px"]),
                symbol_points_range=(int(sym["points_range"][0]), int(sym["points_range"][1])),
                outline_tolerance_px=float(sym["outline_tolerance_px"]),
                inner_tolerance_px=(np.asarray(sym["inner_tolerance_px"], np.float64)
                                    if "inner_tolerance_px" in sym else None),
                edge_contrast=(np.asarray(sym["edge_contrast"], np.float32)
                               if "edge_contrast" in sym else None),
                registration_centres_px=(np.asarray(sym["registration_centres_px"], np.float64)
                                         if "registration_centres_px" in sym else None),
                reference_thumbnail=(_png_from_base64(sym["reference_thumbnail_png"], source)
                                     if "reference_thumbnail_png" in sym else None),
                workspace=Workspace.from_json(data["workspace"]),
                stats=dict(data.get("stats", {})),
            )
        except CalibrationError:
            raise
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise CalibrationError(f"{source}: corrupt calibration file ({type(exc).__name__}: {exc})") from None

    def save(self, path: str | os.PathLike) -> Path:
        """Write the calibration as JSON, atomically (a failed write never destroys a good file)."""
        return write_json(path, self.to_json())


def load_calibration(path: str | os.PathLike) -> Calibration:
    import json

    p = Path(path)
    if not p.is_file():
        raise CalibrationError(f"{p}: no such calibration file")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"{p}: corrupt calibration file (not JSON: {exc})") from None
    return Calibration.from_json(data, source=str(p))


@dataclass(frozen=True, eq=False)
class Shapes:
    """The outer contours of one image that passed the length filter, as polygons."""

    polygons: list[np.ndarray]
    points: np.ndarray  # number of boundary pixels of each contour
    areas: np.ndarray
    centres: np.ndarray  # (n, 2) centre of area (x, y)
    descriptors: np.ndarray  # (n, K)
    n_contours: int  # before the length filter


def extract_shapes(gray: np.ndarray, *, binarizer, extractor, approximator, matcher,
                   points_range: tuple[int, int]) -> Shapes:
    """Binarize, extract, length-filter, approximate and describe the outer contours of an image."""
    from .geometry import centroids, signed_areas

    binary = binarizer.binarize(gray)
    contours = [c for c in extractor.extract(binary) if not c.is_hole]
    kept = [contours[i] for i in np.flatnonzero(length_filter_steps(contours, points_range))]
    approximated = [approximator.approximate(c) for c in kept]
    keep = [i for i, p in enumerate(approximated) if len(p) >= 3]
    polygons = [approximated[i] for i in keep]
    n_points = [len(kept[i].points) for i in keep]
    areas = np.abs(signed_areas(polygons)) if polygons else np.zeros(0)
    nonzero = np.flatnonzero(areas > 0)
    polygons, n_points, areas = [polygons[i] for i in nonzero], [n_points[i] for i in nonzero], areas[nonzero]
    if polygons:
        centres = centroids(polygons).reshape(-1, 2)
        descriptors = matcher.describe_many(polygons)
    else:
        areas, centres = np.zeros(0), np.zeros((0, 2))
        descriptors = matcher.describe_many([])
    return Shapes(polygons, np.asarray(n_points, np.int64), areas, centres, descriptors, len(contours))


def length_filter_steps(contours: list, points_range: tuple[int, int]) -> np.ndarray:
    """The paper's length filter on contour lengths counted in boundary steps (pixels).

    Counting steps, not Euclidean length, needs no Freeman chain, which the hot path skips.
    """
    from .geometry import length_filter

    steps = np.fromiter((len(c.points) for c in contours), np.float64, len(contours))
    return length_filter(steps, min_length=points_range[0], max_length=points_range[1])


def _stage_spec(stage) -> dict[str, Any]:
    return {"name": stage.name, "options": stage.config()}


def _symbol_descriptor_from_image(symbol: Any, *, extractor, approximator, matcher) -> np.ndarray:
    gray = as_gray(load_image(symbol) if isinstance(symbol, (str, os.PathLike)) else symbol, name="symbol")
    # An image of one symbol on a plain ground, at any scale: one global threshold separates them
    # (a local binarizer sized for the floor's symbols would not), and the largest dark shape is it.
    h, w = gray.shape
    shapes = extract_shapes(gray, binarizer=plugins.binarizer("otsu"), extractor=extractor,
                            approximator=approximator, matcher=matcher, points_range=(8, 4 * (h + w)))
    if not shapes.polygons:
        raise CalibrationError("symbol image: no dark shape found in it")
    return shapes.descriptors[int(np.argmax(shapes.areas))]


def update_calibration(calibration: Calibration, frame: Any, **stages: Any) -> tuple[Calibration, Any]:
    """Re-anchor a calibration to the camera's present pose from a frame with obstacles on it.

    The frame is registered to the calibration with the free symbols it shows
    (:mod:`sbplan.registration`), and the calibration is moved by that movement
    (:meth:`Calibration.moved`): detection on later frames then starts from the new pose, with no
    need to empty the floor. Nothing is written here; a movement that cannot be estimated raises
    before anything changes.

    Parameters
    ----------
    calibration : Calibration
    frame : ndarray (H, W) or (H, W, 3), or a path
        A current frame from the moved camera (obstacles allowed).
    **stages
        Stage overrides, as for :func:`sbplan.detection.detect`.

    Returns
    -------
    (Calibration, CameraMotion)
        The moved calibration, and the movement it was moved by.

    Raises
    ------
    CameraMotionError
        The movement cannot be estimated, or is too large to pair symbols with cells.
    """
    from .detection import Detector

    cells = Detector(calibration, **stages).find_cells(frame)
    motion = cells.camera
    updated = calibration.moved(motion.matrix)
    stats = dict(updated.stats)
    stats["updates"] = [*stats.get("updates", []), {**motion.to_json(), "symbols_found": cells.symbols_found}]
    return replace(updated, stats=stats), motion


def calibrate(reference: Any, *, symbol: Any = None, workspace: Workspace | str | os.PathLike | None = None,
              cell_size: float | None = None, binarizer: Any = None, extractor: Any = None,
              approximator: Any = None, matcher: Any = None, mapper: Any = None) -> Calibration:
    """Calibrate on an image of the empty floor.

    Parameters
    ----------
    reference : str, path or ndarray of shape (H, W) or (H, W, 3)
        The reference image (empty floor, every symbol visible).
    symbol : str, path or ndarray, optional
        An image of one reference symbol. When absent, the symbol is inferred as the dominant
        repeated shape of the reference.
    workspace : Workspace or path of a workspace.toml / map folder, optional
        Grid pitch in metres, origin, robot radius, default route.
    cell_size : float, optional
        Grid pitch in metres (both directions) when no workspace is given; default 1.0.
    binarizer, extractor, approximator, matcher, mapper : str or Stage, optional
        Stage names (or instances); defaults in :data:`DEFAULT_STAGES`.

    Raises
    ------
    CalibrationError
        No symbols, an irregular grid, or no shape that repeats.
    """
    gray = as_gray(load_image(reference) if isinstance(reference, (str, os.PathLike)) else reference,
                   name="reference")
    if workspace is not None and not isinstance(workspace, Workspace):
        workspace = load_workspace(workspace)
    if cell_size is not None:
        if not cell_size > 0:
            raise InputError(f"cell_size: must be a positive number of metres, got {cell_size}")
        base = workspace or Workspace()
        workspace = replace(base, pitch_m=(float(cell_size), float(cell_size)), origin_m=base.origin_m)
    workspace = workspace or Workspace()
    reg = plugins.registry()
    chosen = {kind: reg.create(kind, given if given is not None else DEFAULT_STAGES[kind])
              for kind, given in (("binarizer", binarizer), ("extractor", extractor), ("approximator", approximator),
                                  ("matcher", matcher), ("mapper", mapper))}
    h, w = gray.shape
    points_range = (12, max(16, (h + w) // 2))
    kw = dict(extractor=chosen["extractor"], approximator=chosen["approximator"], matcher=chosen["matcher"])
    shapes = extract_shapes(gray, binarizer=chosen["binarizer"], points_range=points_range, **kw)
    given = None if symbol is None else _symbol_descriptor_from_image(
        symbol, extractor=chosen["extractor"], approximator=chosen["approximator"], matcher=chosen["matcher"])
    members = _symbol_members(shapes, chosen["matcher"], ref=given)
    # Fit the binarizer to the symbol size found and run again: a window of a few symbol sizes
    # follows the light without swallowing the symbol itself.
    fit = getattr(chosen["binarizer"], "with_symbol_size", None)
    if fit is not None:
        size = float(np.sqrt(np.median(shapes.areas[members])))
        refit = fit(size * 1.6)
        if refit != chosen["binarizer"]:
            chosen["binarizer"] = refit
            shapes = extract_shapes(gray, binarizer=refit, points_range=points_range, **kw)
            members = _symbol_members(shapes, chosen["matcher"], ref=given)
    reference_descriptor = np.median(shapes.descriptors[members], axis=0)
    dist = chosen["matcher"].distance_matrix(shapes.descriptors, reference_descriptor[None, :])[:, 0]
    grid = fit_grid(shapes.centres[members])
    # What a symbol looks like in later images is not what it looks like in this one: measure the
    # symbols again in degraded copies of the reference (defocus, dimmer light, sensor noise).
    cells = grid.assign(shapes.centres[members])
    cell_area = np.empty((grid.rows, grid.cols))
    cell_area[cells[:, 0], cells[:, 1]] = shapes.areas[members]
    symbol_polygons = [shapes.polygons[i] for i in members[np.argsort(cells[:, 0] * grid.cols + cells[:, 1])]]
    distance_map = signed_distance_map(symbol_polygons, gray.shape)
    degraded, deviations, degraded_polygons, degraded_cells, shifts = _degraded_symbols(
        gray, grid, reference_descriptor, cell_area, distance_map,
        binarizer=chosen["binarizer"], points_range=points_range, **kw)
    # An obstacle that clips a symbol moves part of its outline by more than light and focus
    # move it; the tolerance sits outside what the degraded copies showed, and at least 1 px.
    outline_tolerance = float(max(1.25 * np.max(deviations), 1.0)) if len(deviations) else 3.0
    # ... and the other way round: how far defocus and light pull each reference point in
    ref_points, _ = reference_samples(symbol_polygons)
    inner = inner_deviations(ref_points[degraded_cells], degraded_polygons, shifts)
    inner_tol = (inner_tolerance(inner, degraded_cells, grid.rows * grid.cols) if len(degraded_cells)
                 else np.full((grid.rows * grid.cols, ref_points.shape[1]), outline_tolerance))
    confusers = confuser_distances(chosen["matcher"], reference_descriptor, float(np.median(shapes.areas[members])))
    others = np.concatenate([np.delete(dist, members), confusers])
    threshold, margin = derive_threshold(np.concatenate([dist[members], degraded]), others)
    order = np.argsort(cells[:, 0] * grid.cols + cells[:, 1])
    symbol_idx = members[order]
    others = np.setdiff1d(np.arange(len(shapes.polygons)), members)
    rng = np.random.default_rng(0)  # the sample of other contours is kept small and reproducible
    sample = rng.choice(others, size=min(len(others), 200), replace=False) if len(others) else others
    keep_degraded = rng.choice(len(degraded_polygons), size=min(len(degraded_polygons), 300), replace=False)
    n_points = shapes.points[symbol_idx]
    stats = {
        "contours": shapes.n_contours,
        "after_length_filter": len(shapes.polygons),
        "symbols": int(len(members)),
        "symbol_distance_max": float(dist[members].max()),
        "other_distance_min": float(np.delete(dist, members).min()) if len(others) else None,
        "rejected_centres_px": np.round(shapes.centres[others][:500], 2).tolist(),
    }
    return Calibration(
        image_shape=(h, w),
        stages={k: _stage_spec(v) for k, v in chosen.items()},
        grid=grid,
        symbol_polygons=[shapes.polygons[i] for i in symbol_idx],
        other_polygons=[shapes.polygons[i] for i in sample],
        degraded_polygons=[degraded_polygons[i] for i in sorted(keep_degraded)],
        descriptor=reference_descriptor,
        threshold=threshold,
        margin=margin,
        symbol_area_px=float(np.median(shapes.areas[members])),
        symbol_points_range=(int(n_points.min() * 0.7), int(np.ceil(n_points.max() * 1.4))),
        outline_tolerance_px=outline_tolerance,
        inner_tolerance_px=inner_tol,
        edge_contrast=edge_contrast(gray, *edge_probes(symbol_polygons)),
        registration_centres_px=_registration_centres(gray, symbol_polygons, grid),
        reference_thumbnail=thumbnail(gray),
        workspace=workspace,
        stats=stats,
    )


def _png_base64(image: np.ndarray) -> str:
    ok, buf = cv2.imencode(".png", image)
    return base64.b64encode(buf.tobytes()).decode("ascii")


def _png_from_base64(text: Any, source: str) -> np.ndarray:
    try:
        img = cv2.imdecode(np.frombuffer(base64.b64decode(text, validate=True), np.uint8), cv2.IMREAD_GRAYSCALE)
    except (TypeError, ValueError, binascii.Error):
        img = None
    if img is None:
        raise CalibrationError(f"{source}: symbol.reference_thumbnail_png is not a base64 PNG image")
    return img


def _registration_centres(gray: np.ndarray, symbol_polygons: list[np.ndarray], grid: Grid) -> np.ndarray:
    """Each cell's symbol's grey-level centre (rows, cols, 2): what registration pairs frames'
    symbols with (:func:`sbplan.registration.grey_centres`); the grid's centre where a symbol's
    box leaves the image."""
    boxes = np.array([[p[:, 0].min(), p[:, 1].min(), p[:, 0].max(), p[:, 1].max()] for p in symbol_polygons])
    centres = grey_centres(gray, boxes, centre_window(symbol_polygons))
    fallback = grid.centres_px.reshape(-1, 2)
    bad = ~np.isfinite(centres).all(axis=1)
    centres[bad] = fallback[bad]
    return centres.reshape(grid.rows, grid.cols, 2)


def derive_threshold(symbol_distances: np.ndarray, other_distances: np.ndarray) -> tuple[float, float]:
    """Match threshold from measured distances, and the margin it leaves.

    ``symbol_distances`` are the symbols' distances to the reference descriptor (in the reference
    and in degraded copies of it); ``other_distances`` those of everything that is not a symbol
    (the reference's other contours and the round and rectangular shapes that lighting errors and
    boxes produce). The threshold is twice the farthest symbol, but never beyond halfway to the
    nearest other shape. Returns ``(threshold, margin)``, ``margin = nearest other / farthest
    symbol`` (above 1: they separate).
    """
    d_sym = float(np.max(symbol_distances)) if len(symbol_distances) else 0.0
    d_other = float(np.min(other_distances)) if len(other_distances) else np.inf
    floor = max(d_sym, 1e-6)
    threshold = 2.0 * floor
    if np.isfinite(d_other):
        threshold = min(threshold, d_sym + 0.5 * (d_other - d_sym))
    margin = d_other / floor if np.isfinite(d_other) else float("inf")
    return float(threshold), float(margin)


def confuser_distances(matcher, descriptor: np.ndarray, area: float) -> np.ndarray:
    """Distances from the reference descriptor to shapes a symbol must never be taken for.

    Circles and ellipses (the round contours of lighting errors, the paper's warning) and squares
    and rectangles (boxes, labels), all of the symbol's area.
    """
    t = np.linspace(0, 2 * np.pi, 96, endpoint=False)
    shapes = []
    for aspect in (1.0, 1.3, 1.7, 2.5, 4.0):
        a = np.sqrt(area * aspect / np.pi)
        shapes.append(np.column_stack([a * np.cos(t), a / aspect * np.sin(t)]))
        b = np.sqrt(area * aspect)
        w, h = b / 2, b / aspect / 2
        shapes.append(np.array([[-w, -h], [w, -h], [w, h], [-w, h]]))
    return matcher.distance_matrix(matcher.describe_many(shapes), descriptor[None, :])[:, 0]


def _degraded_symbols(gray: np.ndarray, grid: Grid, descriptor: np.ndarray, cell_area: np.ndarray,
                      distance_map: np.ndarray, *,
                      binarizer, extractor, approximator, matcher, points_range) -> tuple:
    """The reference's symbols in defocused, dimmed, dark-and-grainy and noisy copies of it.

    Returns their descriptor distances to ``descriptor``, their outlines' deviations from the
    reference outlines and common shifts (:func:`sbplan.outline_check.outline_deviation`), their
    polygons and their cells (flat, row-major), as ``(distances, deviations, polygons, cells,
    shifts)``.
    """
    import cv2

    rng = np.random.default_rng(0)  # reproducible noise
    g = gray.astype(np.float64)
    copies = [
        cv2.GaussianBlur(gray, (0, 0), 2.0),
        cv2.convertScaleAbs(gray, alpha=0.6),
        np.clip(0.3 * g + rng.normal(0, 4, g.shape), 0, 255).astype(np.uint8),
        np.clip(g + rng.normal(0, 8, g.shape), 0, 255).astype(np.uint8),
    ]
    distances, deviations, polygons, cells_kept, shifts = [], [], [], [], []
    for image in copies:
        shapes = extract_shapes(image, binarizer=binarizer, extractor=extractor, approximator=approximator,
                                matcher=matcher, points_range=points_range)
        if not shapes.polygons:
            continue
        cells = grid.assign(shapes.centres)
        ok = cells[:, 0] >= 0
        ratio = np.full(len(cells), np.inf)
        ratio[ok] = shapes.areas[ok] / cell_area[cells[ok, 0], cells[ok, 1]]
        ok &= np.abs(np.log(ratio)) < np.log(1.3)
        if not ok.any():  # this degradation erased every symbol: it says nothing about them
            continue
        d = matcher.distance_matrix(shapes.descriptors[ok], descriptor[None, :])[:, 0]
        # one shape per cell: the best match (a cell may also hold the odd noise blob)
        flat = cells[ok, 0] * grid.cols + cells[ok, 1]
        order = np.lexsort((d, flat))
        first = order[np.r_[True, flat[order][1:] != flat[order][:-1]]]
        distances.append(d[first])
        kept = np.flatnonzero(ok)[first]
        dev, shift = outline_deviation([shapes.polygons[i] for i in kept], distance_map, return_shift=True)
        deviations.append(dev)
        shifts.append(shift)
        cells_kept.append(flat[first])
        polygons.extend(shapes.polygons[i] for i in kept)
    if not distances:
        return np.zeros(0), np.zeros(0), [], np.zeros(0, np.int64), np.zeros(0)
    return (np.concatenate(distances), np.concatenate(deviations), polygons, np.concatenate(cells_kept),
            np.concatenate(shifts))


def _symbol_members(shapes: Shapes, matcher, *, ref: np.ndarray | None) -> np.ndarray:
    """Indices of the shapes that are the reference symbol: those near ``ref`` (the descriptor of a
    given symbol image) or, without one, the dominant repeated shape."""
    n = len(shapes.polygons)
    if n == 0:
        raise CalibrationError("no symbols found in the reference image (no dark shapes of symbol size)")
    if ref is not None:
        d = matcher.distance_matrix(shapes.descriptors, ref[None, :])[:, 0]
        near = d < getattr(matcher, "default_threshold", 0.5)
        if not near.any():
            raise CalibrationError("no symbols found in the reference image: no contour matches the given symbol")
        # the symbols also share one size: keep those near the median area of the matches
        area = np.median(shapes.areas[near])
        members = np.flatnonzero(near & (np.abs(shapes.areas / area - 1) < 0.35))
    else:
        members = _dominant_repeated_shape(shapes, matcher)
    if len(members) < 4:
        raise CalibrationError(
            f"no symbol grid found in the reference image: the most repeated shape occurs {len(members)} time(s)")
    return members


def _dominant_repeated_shape(shapes: Shapes, matcher) -> np.ndarray:
    """The largest group of contours with the same shape and the same size."""
    d = matcher.distance_matrix(shapes.descriptors, shapes.descriptors)
    ratio = shapes.areas[:, None] / shapes.areas[None, :]
    same_size = np.abs(np.log(ratio)) < np.log(1.35)
    tight = 0.25 * getattr(matcher, "default_threshold", 0.5)
    alike = (d < tight) & same_size
    seed = int(np.argmax(alike.sum(axis=1)))
    members = np.flatnonzero(alike[seed])
    # widen once around the group's median so the seed's own noise does not decide membership
    median = np.median(shapes.descriptors[members], axis=0)
    dm = matcher.distance_matrix(shapes.descriptors, median[None, :])[:, 0]
    spread = max(float(np.max(dm[members])), 1e-6)
    area = np.median(shapes.areas[members])
    return np.flatnonzero((dm <= 2.0 * spread) & (np.abs(np.log(shapes.areas / area)) < np.log(1.35)))
