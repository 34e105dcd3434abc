"""The calibration file: :class:`Calibration`, everything detection needs, and its JSON format
(``sbplan.calibration/1``, see docs/detection-json.md)."""

from __future__ import annotations

import base64
import binascii
import json
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ... import registry
from ...errors import CalibrationError, SbplanError
from ...imageio import write_json
from ...polygons import signed_areas
from ...workspace import Workspace
from ..grid import Grid
from ..outline_checks import EDGE_SAMPLES, SAMPLES
from ..registration import THUMBNAIL_FACTOR, apply
from .threshold import match_threshold

FORMAT = "sbplan.calibration/1"


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
        common shift, before the symbol counts as partly hidden (see :mod:`sbplan.detection.outline_checks`).
    inner_tolerance_px : ndarray (rows * cols, S) or None
        The other direction: per cell and point of its reference outline (S arc-length samples),
        how far that point may lie outside a found outline, beyond the common shift, as the
        degraded copies showed (:func:`sbplan.detection.outline_checks.inner_tolerance`). None in calibration
        files written before it existed: detection then uses ``outline_tolerance_px`` everywhere.
    edge_contrast : ndarray (rows * cols, EDGE_SAMPLES) or None
        Per cell and point of its reference outline, the relative step from ink to floor the
        reference shows across it (:func:`sbplan.detection.outline_checks.edge_contrast`): detection calls a
        symbol whole that the outline checks failed when its outline still shows a good part of
        this step everywhere. None in calibration files written before it existed (no such rescue).
    registration_centres_px : ndarray (rows, cols, 2) or None
        Every cell's symbol's grey-level centre in the reference
        (:func:`sbplan.detection.registration.grey_centres`), what frames' symbols are compared with
        to register them to sub-pixel accuracy. None in older files: the grid's centres are used.
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
    work_scale: int = 1
    workspace: Workspace = field(default_factory=Workspace)
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def symbols_expected(self) -> int:
        return self.grid.rows * self.grid.cols

    def stage(self, kind: str, override: Any = None):
        """The stage instance of ``kind``: ``override`` (a name or an instance) or the calibrated one."""
        if override is not None:
            return registry.registry().create(kind, override)
        spec = self.stages[kind]
        return registry.registry().create(kind, spec["name"], **spec.get("options", {}))

    def matching_for(self, matcher: Any) -> tuple[np.ndarray, float]:
        """The reference descriptor and the match threshold under ``matcher`` (a stage instance).

        The calibrated ones when ``matcher`` is the calibrated matcher with the same options;
        otherwise derived again from the outlines stored here (the reference's symbols and their
        degraded copies against the sample of other contours) by the rule calibration applies,
        :func:`~sbplan.detection.calibration.threshold.match_threshold`.

        Returns
        -------
        descriptor : ndarray of shape (K,)
        threshold : float
        """
        if (matcher.config() == self.stage("matcher").config()
                and matcher.name == self.stages["matcher"]["name"]):
            return self.descriptor, self.threshold
        descriptor = np.median(matcher.describe_many(self.symbol_polygons), axis=0)
        # the symbols as later images show them: the reference's and its degraded copies'
        seen = matcher.describe_many(self.symbol_polygons + self.degraded_polygons)
        d_sym = matcher.distance_matrix(seen, descriptor[None, :])[:, 0]
        d_other = (matcher.distance_matrix(matcher.describe_many(self.other_polygons), descriptor[None, :])[:, 0]
                   if self.other_polygons else np.zeros(0))
        area = float(np.median(np.abs(signed_areas(self.symbol_polygons))))
        threshold, _ = match_threshold(matcher, descriptor, d_sym, d_other, area=area)
        return descriptor, threshold

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
            **({} if self.work_scale == 1 else {"work_scale": self.work_scale}),
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
            cal = cls(
                image_shape=(int(data["image_shape"][0]), int(data["image_shape"][1])),
                stages={k: dict(v) for k, v in data["stages"].items()},
                work_scale=_work_scale(data.get("work_scale", 1), source),
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
        except SbplanError:
            raise
        except (KeyError, TypeError, ValueError, IndexError, OverflowError, AttributeError) as exc:
            raise CalibrationError(f"{source}: corrupt calibration file ({type(exc).__name__}: {exc})") from None
        problem = cal._inconsistency()
        if problem:
            raise CalibrationError(f"{source}: corrupt calibration file ({problem})")
        return cal

    def _inconsistency(self) -> str | None:
        """What makes this calibration unusable for detection (a file edited or cut short), or None.

        Checked on load, so that detection never meets shapes or values it cannot work with."""
        from ...contracts import KINDS

        h, w = self.image_shape
        if h < 1 or w < 1:
            return f"image_shape {self.image_shape} is empty"
        for kind in [k for k in KINDS if k != "planner"]:
            spec = self.stages.get(kind)
            if not (isinstance(spec, dict) and isinstance(spec.get("name"), str)
                    and isinstance(spec.get("options", {}), dict)):
                return f"stages.{kind} must be {{'name': ..., 'options': {{...}}}}"
        g = self.grid
        cells = g.rows * g.cols
        if g.rows < 1 or g.cols < 1:
            return f"grid of {g.rows} x {g.cols} cells"
        finite = {"grid.centres_px": g.centres_px, "grid.homography": g.homography,
                  "symbol.descriptor": self.descriptor}
        for name, a in finite.items():
            if a.size == 0 or not np.isfinite(a).all():
                return f"{name} must be finite numbers"
        if abs(np.linalg.det(g.homography)) < 1e-12 or not math.isfinite(g.tolerance_px) or g.tolerance_px <= 0:
            return "grid.homography is singular or grid.tolerance_px not > 0"
        if self.descriptor.ndim != 1:
            return "symbol.descriptor must be a list of numbers"
        for name, polys in (("symbol.polygons", self.symbol_polygons), ("other_polygons", self.other_polygons),
                            ("degraded_polygons", self.degraded_polygons)):
            for i, q in enumerate(polys):
                if q.ndim != 2 or q.shape[0] < 3 or q.shape[1] != 2 or not np.isfinite(q).all():
                    return f"{name}[{i}] must be at least 3 finite [x, y] points"
        if len(self.symbol_polygons) != cells:
            return f"symbol.polygons holds {len(self.symbol_polygons)} outlines for {cells} cells"
        values = {"symbol.threshold": self.threshold, "symbol.margin": self.margin,
                  "symbol.area_px": self.symbol_area_px, "symbol.outline_tolerance_px": self.outline_tolerance_px}
        for name, v in values.items():
            if not (math.isfinite(v) and v >= 0):
                return f"{name} must be a finite number >= 0, got {v}"
        lo, hi = self.symbol_points_range
        if not 0 <= lo < hi:
            return f"symbol.points_range must be [low, high] with 0 <= low < high, got {[lo, hi]}"
        shapes = {"symbol.inner_tolerance_px": (self.inner_tolerance_px, (cells, SAMPLES)),
                  "symbol.edge_contrast": (self.edge_contrast, (cells, EDGE_SAMPLES)),
                  "symbol.registration_centres_px": (self.registration_centres_px, (g.rows, g.cols, 2))}
        for name, (a, shape) in shapes.items():
            if a is not None and (a.shape != shape or not np.isfinite(a).all()):
                return f"{name} must be finite numbers of shape {shape}, got shape {a.shape}"
        if self.reference_thumbnail is not None and self.reference_thumbnail.ndim != 2:
            return "symbol.reference_thumbnail_png must be a grey image"
        return None

    def save(self, path: str | os.PathLike) -> Path:
        """Write the calibration as JSON, atomically (a failed write never destroys a good file)."""
        return write_json(path, self.to_json())


def _work_scale(value: Any, source: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 64:
        raise CalibrationError(f"{source}: work_scale must be a whole number from 1 to 64, got {value!r}")
    return value


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


def load_calibration(path: str | os.PathLike) -> Calibration:
    p = Path(path)
    if not p.is_file():
        raise CalibrationError(f"{p}: no such calibration file")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"{p}: corrupt calibration file (not JSON: {exc})") from None
    return Calibration.from_json(data, source=str(p))
