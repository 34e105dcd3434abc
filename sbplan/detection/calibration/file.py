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

from ... import limits, registry
from ...contracts import DescriptorMatcher, Stage, descriptors_of, distances_between
from ...errors import CalibrationFileError, InputError, MapFormatError, PluginError, UnknownStageError
from ...imageio import image_size, write_json
from ...polygons import signed_areas
from ...workspace import Workspace
from ..grid import Grid
from ..outline_checks import EDGE_SAMPLES, SAMPLES
from ..registration import THUMBNAIL_FACTOR, apply
from .threshold import match_threshold

FORMAT = "sbplan.calibration/1"

#: Automatic stage options (``with_symbol_size``) are fitted to this many symbol sizes, at
#: calibration and when a calibration's stage is made.
SYMBOL_WINDOW = 1.6

#: The stages a calibration names, one of each kind.
STAGE_KINDS = ("binarizer", "extractor", "approximator", "matcher", "mapper")
#: Stage kinds a calibration file may lack (written before they existed): the default is used.
OPTIONAL_STAGE_KINDS = ("footprint",)


@dataclass(frozen=True, eq=False)
class Calibration:
    """Everything detection needs, fitted on a reference image.

    Attributes
    ----------
    image_shape : (H, W)
    stages : dict
        kind -> ``{"name": ..., "options": {...}}`` for binarizer, extractor, approximator, matcher,
        mapper and footprint (files written before the footprint stage existed lack it: the
        default is used).
    grid : Grid
    symbol_polygons : list of ndarray (K, 2)
        The approximated outline of every cell's symbol in the reference, row-major.
    symbol_holes : list of list of ndarray (K, 2), or None
        The holes in every cell's symbol in the reference (a letter A's triangle, a P's counter),
        row-major like ``symbol_polygons``: floor that belongs to the symbol, which the scratch
        repair must not take for a scratch. None in files written before it existed (the repair
        then finds holes in the frame alone).
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
    reference_thumbnail : ndarray (H // 4, W // 4), uint8, or None
        The reference averaged over 4 x 4 blocks: registration tells movements a pitch apart by the
        floor's texture in it, and the ``pixels`` footprint compares frames with it
        (:mod:`sbplan.detection.footprints`). None in older files (no texture check; cell footprints).
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
    symbol_holes: list[list[np.ndarray]] | None = None
    workspace: Workspace = field(default_factory=Workspace)
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def symbols_expected(self) -> int:
        return self.grid.rows * self.grid.cols

    def stage(self, kind: str, override: str | Stage | None = None):
        """The stage instance of ``kind``: ``override`` (a name or an instance) or the calibrated one.

        A stage with options set to "from the symbol size" (``with_symbol_size``, as the local
        binarizers' ``window=0``) gets them fitted to this calibration's symbols, as calibration
        fits them: an override named at detection, or a file whose options were left automatic,
        does not fall back to sizes made for no floor in particular."""
        if override is not None:
            stage = registry.registry().create(kind, override)
        elif kind not in self.stages:
            # a file written before the kind existed (the footprint): the default stage
            from .calibrate import DEFAULT_STAGES

            stage = registry.registry().create(kind, DEFAULT_STAGES[kind])
        else:
            spec = self.stages[kind]
            stage = registry.registry().create(kind, spec["name"], **spec.get("options", {}))
        fit = getattr(stage, "with_symbol_size", None)
        if fit is not None and not isinstance(override, Stage):
            stage = fit(math.sqrt(self.symbol_area_px) * SYMBOL_WINDOW / self.work_scale)
        return stage

    def matching_for(self, matcher: DescriptorMatcher) -> tuple[np.ndarray, float]:
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
        descriptor = np.median(descriptors_of(matcher, self.symbol_polygons), axis=0)
        # the symbols as later images show them: the reference's and its degraded copies'
        seen = descriptors_of(matcher, self.symbol_polygons + self.degraded_polygons)
        d_sym = distances_between(matcher, seen, descriptor[None, :])[:, 0]
        d_other = (distances_between(matcher, descriptors_of(matcher, self.other_polygons), descriptor[None, :])[:, 0]
                   if self.other_polygons else np.zeros(0))
        area = float(np.median(np.abs(signed_areas(self.symbol_polygons))))
        threshold, _ = match_threshold(matcher, descriptor, d_sym, d_other, area=area)
        return descriptor, threshold

    def pixels_to_world(self, xy: np.ndarray) -> np.ndarray:
        """Image pixels ``(x, y)`` (N, 2) -> world metres ``(x, y)`` (N, 2), through the grid."""
        lattice = self.grid.px_to_lattice(xy)
        return self.workspace.lattice_to_world(lattice, self.grid.rows)

    def world_to_pixels(self, xy: np.ndarray) -> np.ndarray:
        """World metres ``(x, y)`` (N, 2) -> image pixels ``(x, y)`` (N, 2): the inverse of
        :meth:`pixels_to_world` (what the planner avoids, drawn on the image)."""
        lattice = self.workspace.world_to_lattice(xy, self.grid.rows)
        return self.grid.lattice_to_px(lattice)

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
            symbol_holes=(None if self.symbol_holes is None
                          else [[apply(matrix, h) for h in holes] for holes in self.symbol_holes]),
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
                **({} if self.symbol_holes is None else
                   {"holes": [[np.round(h, 3).tolist() for h in holes] for holes in self.symbol_holes]}),
            },
            "other_polygons": [np.round(p, 3).tolist() for p in self.other_polygons],
            "degraded_polygons": [np.round(p, 3).tolist() for p in self.degraded_polygons],
            "workspace": self.workspace.to_json(),
            "stats": self.stats,
        }

    @classmethod
    def from_json(cls, data: Any, *, source: str = "calibration") -> "Calibration":
        """A calibration from its JSON form, every field checked first.

        Raises
        ------
        CalibrationFileError
            Not a calibration, another format version, or a field of the wrong type or shape, not
            finite, or out of range; the message names ``source`` and the field.
        """
        if not isinstance(data, dict) or "format" not in data:
            raise CalibrationFileError(f"{source}: not an sbplan calibration file")
        if data["format"] != FORMAT:
            raise CalibrationFileError(
                f"{source}: calibration format {data['format']!r} is not supported (expected {FORMAT!r}); "
                "re-run 'sbplan calibrate' on the reference image")
        f = _Fields(source)
        shape = f.ints(data, "image_shape", 2, low=1)
        limits.check("image_pixels", shape[0] * shape[1], f"{source}: image_shape {shape[0]} x {shape[1]}")
        stages = f.stages(data)
        grid_data = f.mapping(data, "grid")
        rows, cols = (f.ints(grid_data, k, None, low=1, field=f"grid.{k}") for k in ("rows", "cols"))
        limits.check("image_pixels", rows * cols, f"{source}: grid of {rows} x {cols} cells")
        grid = Grid(rows, cols, f.array(grid_data, "centres_px", (rows, cols, 2), field="grid.centres_px"),
                    f.array(grid_data, "homography", (3, 3), field="grid.homography"),
                    f.number(grid_data, "tolerance_px", positive=True, field="grid.tolerance_px"))
        if abs(np.linalg.det(grid.homography)) < 1e-12:
            raise CalibrationFileError(f"{source}: grid.homography: is singular (maps the grid to a line)")
        n_cells = rows * cols
        sym = f.mapping(data, "symbol")
        polygons = f.polygons(sym, "polygons", field="symbol.polygons")
        if len(polygons) != n_cells:
            raise CalibrationFileError(f"{source}: symbol.polygons: {len(polygons)} outlines for a grid of "
                                       f"{rows} x {cols} = {n_cells} cells")
        holes = None
        if "holes" in sym:
            if not isinstance(sym["holes"], list) or len(sym["holes"]) != n_cells:
                raise CalibrationFileError(f"{source}: symbol.holes: expected a list of holes for each of the "
                                           f"{n_cells} cells")
            holes = [f.polygons({"holes": cell}, "holes", field=f"symbol.holes[{i}]")
                     for i, cell in enumerate(sym["holes"])]
        descriptor = f.array(sym, "descriptor", (None,), field="symbol.descriptor")
        if not len(descriptor):
            raise CalibrationFileError(f"{source}: symbol.descriptor: is empty")
        lo, hi = f.ints(sym, "points_range", 2, low=1, field="symbol.points_range")
        if lo > hi:
            raise CalibrationFileError(f"{source}: symbol.points_range: [{lo}, {hi}] runs backwards")
        margin = f.number(sym, "margin", field="symbol.margin", allow_inf=True)
        if margin < 0:
            raise CalibrationFileError(f"{source}: symbol.margin: must be >= 0, got {margin}")
        thumb = None
        if "reference_thumbnail_png" in sym:
            thumb = _png_from_base64(sym["reference_thumbnail_png"], source)
            expected = (max(1, shape[0] // THUMBNAIL_FACTOR), max(1, shape[1] // THUMBNAIL_FACTOR))
            if thumb.shape != expected:
                raise CalibrationFileError(
                    f"{source}: symbol.reference_thumbnail_png: is {thumb.shape[1]} x {thumb.shape[0]} pixels, "
                    f"expected {expected[1]} x {expected[0]} for a {shape[1]} x {shape[0]} image")
        try:
            workspace = Workspace.from_json(f.mapping(data, "workspace"))
        except (MapFormatError, KeyError, TypeError, ValueError, IndexError) as exc:
            raise CalibrationFileError(f"{source}: workspace: {exc}") from None
        stats = data.get("stats", {})
        if not isinstance(stats, dict):
            raise CalibrationFileError(f"{source}: stats: expected an object")
        return cls(
            image_shape=(shape[0], shape[1]),
            stages=stages,
            work_scale=_work_scale(data.get("work_scale", 1), source),
            grid=grid,
            symbol_polygons=polygons,
            symbol_holes=holes,
            other_polygons=f.polygons(data, "other_polygons"),
            degraded_polygons=f.polygons(data, "degraded_polygons"),
            descriptor=descriptor,
            threshold=f.number(sym, "threshold", positive=True, field="symbol.threshold"),
            margin=margin,
            symbol_area_px=f.number(sym, "area_px", positive=True, field="symbol.area_px"),
            symbol_points_range=(lo, hi),
            outline_tolerance_px=f.number(sym, "outline_tolerance_px", positive=True,
                                          field="symbol.outline_tolerance_px"),
            inner_tolerance_px=f.optional_array(sym, "inner_tolerance_px", (n_cells, SAMPLES), low=0.0,
                                                field="symbol.inner_tolerance_px"),
            edge_contrast=(None if "edge_contrast" not in sym else
                           f.array(sym, "edge_contrast", (n_cells, EDGE_SAMPLES),
                                   field="symbol.edge_contrast").astype(np.float32)),
            registration_centres_px=f.optional_array(sym, "registration_centres_px", (rows, cols, 2),
                                                     field="symbol.registration_centres_px"),
            reference_thumbnail=thumb,
            workspace=workspace,
            stats=dict(stats),
        )

    def save(self, path: str | os.PathLike) -> Path:
        """Write the calibration as JSON, atomically (a failed write never destroys a good file)."""
        return write_json(path, self.to_json())


class _Fields:
    """Reads a calibration's fields, each checked, with errors naming the file and the field."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, field: str, what: str) -> CalibrationFileError:
        return CalibrationFileError(f"{self.source}: {field}: {what}")

    def get(self, data: dict, key: str, field: str) -> Any:
        if not isinstance(data, dict):
            raise self.fail(field.rsplit(".", 1)[0] if "." in field else field, "expected an object")
        if key not in data:
            raise self.fail(field, "missing")
        return data[key]

    def mapping(self, data: dict, key: str, field: str | None = None) -> dict:
        v = self.get(data, key, field or key)
        if not isinstance(v, dict):
            raise self.fail(field or key, f"expected an object, got {type(v).__name__}")
        return v

    def number(self, data: dict, key: str, *, field: str, positive: bool = False, allow_inf: bool = False) -> float:
        v = self.get(data, key, field)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(field, f"expected a number, got {_short(v)}")
        x = float(v)
        if math.isnan(x) or (math.isinf(x) and not allow_inf):
            raise self.fail(field, f"must be finite, got {x}")
        if positive and not x > 0:
            raise self.fail(field, f"must be > 0, got {x:g}")
        return x

    def ints(self, data: dict, key: str, n: int | None, *, low: int, field: str | None = None):
        field = field or key
        v = self.get(data, key, field)
        items = [v] if n is None else v
        if n is not None and (not isinstance(v, list) or len(v) != n):
            raise self.fail(field, f"expected {n} integers, got {_short(v)}")
        out = []
        for x in items:
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or x != int(x):
                raise self.fail(field, f"expected integers, got {_short(v)}")
            if x < low:
                raise self.fail(field, f"must be >= {low}, got {_short(v)}")
            out.append(int(x))
        return out[0] if n is None else out

    def array(self, data: dict, key: str, shape: tuple, *, field: str, low: float | None = None) -> np.ndarray:
        v = self.get(data, key, field)
        try:
            a = np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError):
            raise self.fail(field, "expected numbers in nested lists") from None
        if a.ndim != len(shape) or any(e is not None and e != g for e, g in zip(shape, a.shape)):
            want = " x ".join("n" if e is None else str(e) for e in shape)
            raise self.fail(field, f"expected shape ({want}), got {a.shape}")
        if not np.isfinite(a).all():
            raise self.fail(field, "holds NaN or infinite values")
        if low is not None and a.size and a.min() < low:
            raise self.fail(field, f"holds values below {low:g}")
        return a

    def optional_array(self, data: dict, key: str, shape: tuple, *, field: str, low: float | None = None):
        return self.array(data, key, shape, field=field, low=low) if key in data else None

    def polygons(self, data: dict, key: str, *, field: str | None = None) -> list[np.ndarray]:
        field = field or key
        v = self.get(data, key, field)
        if not isinstance(v, list):
            raise self.fail(field, f"expected a list of outlines, got {_short(v)}")
        out = []
        for i, p in enumerate(v):
            try:
                a = np.asarray(p, dtype=np.float64)
            except (TypeError, ValueError):
                raise self.fail(f"{field}[{i}]", "expected [x, y] points") from None
            if a.ndim != 2 or a.shape[1] != 2 or len(a) < 3:
                raise self.fail(f"{field}[{i}]", f"expected at least 3 [x, y] points, got shape {a.shape}")
            if not np.isfinite(a).all():
                raise self.fail(f"{field}[{i}]", "holds NaN or infinite values")
            out.append(a)
        return out

    def stages(self, data: dict) -> dict[str, dict[str, Any]]:
        stages = self.mapping(data, "stages")
        out = {}
        for kind in STAGE_KINDS + OPTIONAL_STAGE_KINDS:
            if kind in OPTIONAL_STAGE_KINDS and kind not in stages:
                continue
            spec = self.mapping(stages, kind, f"stages.{kind}")
            name = self.get(spec, "name", f"stages.{kind}.name")
            if not isinstance(name, str) or not name:
                raise self.fail(f"stages.{kind}.name", f"expected a stage name, got {_short(name)}")
            options = spec.get("options", {})
            if not isinstance(options, dict):
                raise self.fail(f"stages.{kind}.options", "expected an object")
            try:
                registry.registry().info(kind, name)
            except UnknownStageError:
                pass  # a plugin not installed here: said when a detector needs it
            else:
                try:  # the stage checks its own options
                    registry.registry().create(kind, name, **options)
                except (InputError, PluginError) as exc:
                    raise self.fail(f"stages.{kind}.options", str(exc)) from None
            out[kind] = {"name": name, "options": dict(options)}
        return out


def _short(v: Any) -> str:
    text = json.dumps(v, default=str) if not isinstance(v, float) else repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def _work_scale(value: Any, source: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 64:
        raise CalibrationFileError(f"{source}: work_scale: must be a whole number from 1 to 64, got {value!r}")
    return value


def _png_base64(image: np.ndarray) -> str:
    ok, buf = cv2.imencode(".png", image)
    return base64.b64encode(buf.tobytes()).decode("ascii")


def _png_from_base64(text: Any, source: str) -> np.ndarray:
    field = f"{source}: symbol.reference_thumbnail_png"
    try:
        data = base64.b64decode(text, validate=True)
    except (TypeError, ValueError, binascii.Error):
        raise CalibrationFileError(f"{field}: is not base64 text") from None
    size = image_size(data)
    if not data.startswith(b"\x89PNG") or size is None:
        raise CalibrationFileError(f"{field}: is not a PNG image")
    limits.check("image_pixels", size[0] * size[1], f"{field}: {size[0]} x {size[1]} pixels")
    try:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
    except cv2.error:
        img = None
    if img is None:
        raise CalibrationFileError(f"{field}: is not a readable PNG image")
    return img


#: Calibration files hold the outlines of every symbol; one larger than this is not a calibration.
MAX_FILE_BYTES = 1 << 30


def load_calibration(path: str | os.PathLike) -> Calibration:
    """Read and check a calibration file (see :meth:`Calibration.from_json`).

    Raises
    ------
    CalibrationFileError
        No such file, not a regular file, not JSON, or a field detection cannot use.
    """
    p = Path(path)
    if not p.exists():
        raise CalibrationFileError(f"{p}: no such calibration file")
    if not p.is_file():
        raise CalibrationFileError(f"{p}: is not a calibration file (a folder, device or FIFO)")
    if p.stat().st_size > MAX_FILE_BYTES:
        raise CalibrationFileError(f"{p}: {p.stat().st_size:,} bytes is too large for a calibration file")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise CalibrationFileError(f"{p}: corrupt calibration file (not JSON: {exc})") from None
    except RecursionError:
        raise CalibrationFileError(f"{p}: corrupt calibration file (nested too deeply to be a calibration)") from None
    except OSError as exc:
        raise CalibrationFileError(f"{p}: cannot be read ({exc.strerror})") from None
    return Calibration.from_json(data, source=str(p))
