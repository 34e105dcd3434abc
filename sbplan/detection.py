"""Detection (paper section 4): which cells are occupied, and the obstacles they form.

The hot path: binarize -> extract -> length filter -> approximate -> describe and match ->
assign to cells -> occupancy image -> obstacles. :class:`Detector` does the per-calibration work
once (stages, reference descriptors, thresholds), so a stream of frames pays only for the image.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .calibration import Calibration, confuser_distances, derive_threshold, length_filter_steps, load_calibration
from .errors import DetectionError
from .geometry import centroids, signed_areas
from .imageio import as_gray, load_image
from .obstacles import Obstacle, find_obstacles
from .outline_check import INNER_MARGIN_PX, hidden_piece, outline_deviation, reference_samples, signed_distance_map

FORMAT = "sbplan.detection/1"


@dataclass(frozen=True, eq=False)
class Detection:
    """The result of one detection.

    Attributes
    ----------
    occupied : ndarray of shape (rows, cols), bool
        True where the cell's symbol is missing; ``[row, col]``, row 0 at the top.
    symbols_found : int
    matched_centres_px : ndarray of shape (n, 2)
        Centres ``(x, y)`` of the matched symbols that were assigned to a cell.
    occupancy : ndarray of shape (H, W), uint8
        The occupancy image (0 occupied, 255 free), paper figure 14.
    obstacles : list of Obstacle
    timings_ms : dict
        Milliseconds per stage, in pipeline order, and "total".
    stages : dict
        kind -> stage name used.
    """

    calibration: Calibration
    occupied: np.ndarray
    symbols_found: int
    matched_centres_px: np.ndarray
    occupancy: np.ndarray
    obstacles: list[Obstacle]
    timings_ms: dict[str, float]
    stages: dict[str, str]
    candidates_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def occupied_cells(self) -> list[tuple[int, int]]:
        return [(int(r), int(c)) for r, c in zip(*np.nonzero(self.occupied))]

    @property
    def symbols_expected(self) -> int:
        return self.calibration.symbols_expected

    def to_json(self) -> dict:
        cal = self.calibration
        return {
            "format": FORMAT,
            "image": {"width": cal.image_shape[1], "height": cal.image_shape[0]},
            "grid": {"rows": cal.grid.rows, "cols": cal.grid.cols},
            "symbols_expected": self.symbols_expected,
            "symbols_found": self.symbols_found,
            "occupied_cells": [list(c) for c in self.occupied_cells],
            "free_cells": int((~self.occupied).sum()),
            "obstacles": [o.to_json() for o in self.obstacles],
            "workspace": {
                "bounds_m": [round(v, 6) for v in cal.world_bounds()],
                "pitch_m": list(cal.workspace.pitch_m),
                "origin_m": list(cal.workspace.origin),
                "robot_radius_m": cal.workspace.robot_radius_m,
                "frame": "metres; x right along the columns, y up toward row 0",
            },
            "stages": dict(self.stages),
            "timings_ms": {k: round(v, 4) for k, v in self.timings_ms.items()},
        }


class Detector:
    """Detection with one calibration and one choice of stages, reusable across frames.

    Stage arguments are names or instances; None means the calibrated stage. When the matcher or
    approximator differs from the calibrated one, the reference descriptor and the threshold are
    derived again from the reference symbols stored in the calibration.
    """

    def __init__(self, calibration: Calibration, *, binarizer: Any = None, extractor: Any = None,
                 approximator: Any = None, matcher: Any = None, mapper: Any = None):
        self.calibration = cal = calibration
        self.binarizer = cal.stage("binarizer", binarizer)
        self.extractor = cal.stage("extractor", extractor)
        if "chains" in self.extractor.config() and self.extractor.config()["chains"]:
            # Freeman chains are for the paper's KKA; skip them on the hot path when nobody needs them.
            from dataclasses import replace
            if (approximator or cal.stages["approximator"]["name"]) != "kka":
                self.extractor = replace(self.extractor, chains=False)
        self.approximator = cal.stage("approximator", approximator)
        self.matcher = cal.stage("matcher", matcher)
        self.mapper = cal.stage("mapper", mapper)
        same_shapes = (self.matcher.config() == cal.stage("matcher").config() and self.matcher.name == cal.stages["matcher"]["name"])
        if same_shapes:
            self.descriptor, self.threshold = cal.descriptor, cal.threshold
        else:
            sym = self.matcher.describe_many(cal.symbol_polygons)
            self.descriptor = np.median(sym, axis=0)
            # the symbols as later images show them: the reference's and its degraded copies'
            seen = self.matcher.describe_many(cal.symbol_polygons + cal.degraded_polygons)
            d_sym = self.matcher.distance_matrix(seen, self.descriptor[None, :])[:, 0]
            area = float(np.median(np.abs(signed_areas(cal.symbol_polygons))))
            d_other = confuser_distances(self.matcher, self.descriptor, area)
            if cal.other_polygons:
                other = self.matcher.describe_many(cal.other_polygons)
                d_other = np.concatenate([d_other, self.matcher.distance_matrix(other, self.descriptor[None, :])[:, 0]])
            self.threshold, _ = derive_threshold(d_sym, d_other)
        areas = np.abs(signed_areas(cal.symbol_polygons))
        self.cell_area = areas.reshape(cal.grid.rows, cal.grid.cols)
        self.distance_map = signed_distance_map(cal.symbol_polygons, cal.image_shape)
        # each cell's reference outline points, moved into the symbol by what light and focus pull
        # them in (calibrated per point) plus a margin: a found symbol must cover them all
        self.ref_points, self.inward = reference_samples(cal.symbol_polygons)
        tol = cal.inner_tolerance_px if cal.inner_tolerance_px is not None else cal.outline_tolerance_px
        self.allowance = np.broadcast_to(tol, self.ref_points.shape[:2]) + INNER_MARGIN_PX
        self.stage_names = {"binarizer": self.binarizer.name, "extractor": self.extractor.name,
                            "approximator": self.approximator.name, "matcher": self.matcher.name,
                            "mapper": self.mapper.name}

    def __call__(self, image: Any) -> Detection:
        cal = self.calibration
        timings: dict[str, float] = {}
        t0 = t = time.perf_counter()

        def lap(name: str) -> None:
            nonlocal t
            now = time.perf_counter()
            timings[name] = (now - t) * 1e3
            t = now

        gray = as_gray(load_image(image) if isinstance(image, (str, os.PathLike)) else image, name="image")
        if gray.shape != tuple(cal.image_shape):
            raise DetectionError(
                f"image is {gray.shape[1]}x{gray.shape[0]} but the calibration is for "
                f"{cal.image_shape[1]}x{cal.image_shape[0]}; calibrate on a reference from the same camera")
        binary = self.binarizer.binarize(gray)
        lap("binarize")
        contours = self.extractor.extract(binary)
        lap("extract")
        outer = [c for c in contours if not c.is_hole]
        kept = [outer[i] for i in np.flatnonzero(length_filter_steps(outer, cal.symbol_points_range))]
        polygons = [self.approximator.approximate(c) for c in kept]
        polygons = [p for p in polygons if len(p) >= 3]
        lap("approximate")
        rows, cols = cal.grid.shape
        found = np.zeros((rows, cols), bool)
        matched = np.zeros((0, 2))
        candidates = np.zeros((0, 2))
        if polygons:
            desc = self.matcher.describe_many(polygons)
            d = self.matcher.distance_matrix(desc, self.descriptor[None, :])[:, 0]
            lap("describe")
            hit = np.flatnonzero(d < self.threshold)
            if len(hit):
                hit_polygons = [polygons[i] for i in hit]
                centres = centroids(hit_polygons, on_zero_area="nan").reshape(-1, 2)
                areas = np.abs(signed_areas(hit_polygons))
                cells = cal.grid.assign(centres)
                ok = cells[:, 0] >= 0
                # A fixed camera sees each cell's symbol at one size. Light and focus scale every
                # symbol alike, so the frame's median ratio is divided out; what remains is a
                # symbol grown or shrunk on its own: partly hidden, or not the symbol at all.
                ratio = np.full(len(hit), np.inf)
                ratio[ok] = areas[ok] / self.cell_area[cells[ok, 0], cells[ok, 1]]
                ok &= np.abs(np.log(ratio)) < np.log(1.3)
                # ... and at one place: an outline that strays from its cell's reference outline
                # more than light and focus make it is partly hidden.
                if ok.any():
                    idx = np.flatnonzero(ok)
                    deviation, shift = outline_deviation([hit_polygons[i] for i in idx], self.distance_map,
                                                         return_shift=True)
                    # ... and one that left out a piece of its cell's reference outline is too
                    flat = cells[idx, 0] * cols + cells[idx, 1]
                    hidden = hidden_piece([hit_polygons[i] for i in idx], shift, self.ref_points[flat],
                                          self.inward[flat], self.allowance[flat], binary)
                    ok[idx[(deviation > cal.outline_tolerance_px) | hidden]] = False
                found[cells[ok, 0], cells[ok, 1]] = True
                matched, candidates = centres[ok], centres[~ok]
        else:
            lap("describe")
        lap("match")
        occupied = ~found
        occupancy = self.mapper.occupancy_image(cal.grid, occupied, gray.shape)
        lap("map")
        obstacles = find_obstacles(occupancy, occupied, cal.grid, to_world=cal.pixels_to_world)
        lap("obstacles")
        timings["total"] = (time.perf_counter() - t0) * 1e3
        return Detection(cal, occupied, int(found.sum()), matched, occupancy, obstacles, timings,
                         self.stage_names, candidates)


def detect(image: Any, calibration: Calibration | str | os.PathLike, **stages: Any) -> Detection:
    """Detect the occupied cells and obstacles of one image.

    Parameters
    ----------
    image : ndarray of shape (H, W) or (H, W, 3), or a path
        The current image, from the camera of the calibration.
    calibration : Calibration or path of a calibration JSON
    **stages : str or Stage
        ``binarizer``, ``extractor``, ``approximator``, ``matcher``, ``mapper`` overrides.

    Raises
    ------
    DetectionError
        The image's size differs from the calibration's.
    """
    if not isinstance(calibration, Calibration):
        calibration = load_calibration(calibration)
    return Detector(calibration, **stages)(image)
