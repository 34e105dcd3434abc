"""Detection (paper section 4): which cells are occupied, and the obstacles they form.

The hot path: binarize -> extract -> length filter -> approximate -> describe and match ->
assign to cells -> occupancy image -> obstacles. :class:`Detector` does the per-calibration work
once (stages, reference descriptors, thresholds), so a stream of frames pays only for the image.
"""

from __future__ import annotations

import collections.abc
import os
import time
from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import DetectionError
from ..imageio import as_gray, load_image
from ..polygons import PolygonBatch, centroids, resample_complex, signed_areas
from .bands import RowBands
from .calibration.file import Calibration, load_calibration
from .calibration.shapes import length_filter_steps
from .obstacles import find_obstacles
from .outline_checks import (EDGE_SAMPLES, INNER_MARGIN_PX, SAMPLES, edge_factors, edge_probes, edges_intact,
                             hidden_piece, reference_samples, samples_deviation, signed_distance_map)
from .result import CellDetection, Detection

#: Row bands reach this many symbol sizes (and at least BAND_MARGIN_PX) above and below the
#: reference symbols: room for defocus and small camera shake.
BAND_MARGIN = 0.25
BAND_MARGIN_PX = 6.0
#: Bands are used when they cover at most this fraction of the frame's rows.
BANDS_WORTH_IT = 0.8


class Detector:
    """Detection with one calibration and one choice of stages, reusable across frames.

    Stage arguments are names or instances; None means the calibrated stage. A matcher other than
    the calibrated one (by name or options) takes its reference descriptor and threshold from
    :meth:`Calibration.matching_for`.

    With ``row_bands`` (the default) the per-pixel work is limited to the rows around the
    reference's symbols when they are at most 80 % of the frame (:mod:`sbplan.detection.bands`);
    the cells found are the same as on whole frames, at about half the cost. ``row_bands=False``
    processes whole frames.
    """

    def __init__(self, calibration: Calibration, *, binarizer: Any = None, extractor: Any = None,
                 approximator: Any = None, matcher: Any = None, mapper: Any = None, row_bands: bool = True):
        self.calibration = cal = calibration
        self.binarizer = cal.stage("binarizer", binarizer)
        self.extractor = cal.stage("extractor", extractor)
        if "chains" in self.extractor.config() and self.extractor.config()["chains"]:
            # Freeman chains are for the paper's KKA; skip them on the hot path when nobody needs them.
            if (approximator or cal.stages["approximator"]["name"]) != "kka":
                self.extractor = replace(self.extractor, chains=False)
        self.approximator = cal.stage("approximator", approximator)
        self.matcher = cal.stage("matcher", matcher)
        self.mapper = cal.stage("mapper", mapper)
        self.descriptor, self.threshold = cal.matching_for(self.matcher)
        areas = np.abs(signed_areas(cal.symbol_polygons))
        self.cell_area = areas.reshape(cal.grid.rows, cal.grid.cols)
        # what find_cells reads per frame, made once: cell areas by flat cell number, the ratio bound
        self._cell_area_flat = self.cell_area.ravel()
        self._log_area_tolerance = np.log(1.3)
        self.distance_map = signed_distance_map(cal.symbol_polygons, cal.image_shape)
        # each cell's reference outline points, moved into the symbol by what light and focus pull
        # them in (calibrated per point) plus a margin: a found symbol must cover them all
        self.ref_points, self.inward = reference_samples(cal.symbol_polygons)
        tol = cal.inner_tolerance_px if cal.inner_tolerance_px is not None else cal.outline_tolerance_px
        self.allowance = np.broadcast_to(tol, self.ref_points.shape[:2]) + INNER_MARGIN_PX
        # Symbols only appear in the rows where the reference showed them; when those rows are a
        # clear part of the frame, the per-pixel work is limited to them (sbplan.detection.bands), and the
        # reference data the checks compare with is laid out the same way.
        self.bands: RowBands | None = None
        self._band_distance_map, self._band_ref_points = self.distance_map, self.ref_points
        if row_bands and cal.symbol_polygons:
            size = float(np.sqrt(np.median(areas)))
            bands = RowBands.around(cal.symbol_polygons, cal.image_shape, margin=max(BAND_MARGIN_PX, BAND_MARGIN * size))
            if bands.fraction <= BANDS_WORTH_IT:
                self.bands = bands
                # separators read "far from any outline": an outline touching one is not a symbol
                self._band_distance_map = bands.stack(self.distance_map, fill=np.float32(1e3))
                self._band_ref_points = bands.to_stacked(self.ref_points.reshape(-1, 2)).reshape(self.ref_points.shape)
        # the length filter's bounds, checked once (length_filter raises on bad ones)
        length_filter_steps([], cal.symbol_points_range)
        self._points_range = (float(cal.symbol_points_range[0]), float(cal.symbol_points_range[1]))
        # The reference points and inward normals with x and y as planes (cell, 2, samples), handed
        # to hidden_piece as (n, samples, 2) views: its arithmetic keeps that layout, so the probes'
        # x and y go to cv2.remap as rows of contiguous floats, without the two copies an
        # interleaved (..., 2) array costs.
        self._ref_planes = np.ascontiguousarray(self._band_ref_points.transpose(0, 2, 1))
        self._inward_planes = np.ascontiguousarray(self.inward.transpose(0, 2, 1))
        # A cell the outline checks call occupied is free after all when the grey image still shows
        # its symbol's edge all around (sbplan.detection.outline_checks.edges_intact): where each reference
        # outline is read, and the step the reference showed there. Old calibrations have none.
        n_cells = len(cal.symbol_polygons)
        self._edge_x = self._edge_y = self._edge_factors = None
        if cal.edge_contrast is not None and np.shape(cal.edge_contrast) == (n_cells, EDGE_SAMPLES) and n_cells:
            self._edge_x, self._edge_y = edge_probes(cal.symbol_polygons)
            self._edge_factors = edge_factors(cal.edge_contrast)
            self._cell_centres = centroids(cal.symbol_polygons)
        self.stage_names = {"binarizer": self.binarizer.name, "extractor": self.extractor.name,
                            "approximator": self.approximator.name, "matcher": self.matcher.name,
                            "mapper": self.mapper.name}

    def find_cells(self, image: Any) -> CellDetection:
        """Image in -> occupied cells out: the pipeline up to the mapper, for callers that need
        only the cells (and what :meth:`__call__` builds on).

        Raises
        ------
        DetectionError
            The image's size differs from the calibration's.
        """
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
        if self.bands is not None:
            binary = self.binarizer.binarize_bands(gray, self.bands)
        else:
            binary = self.binarizer.binarize(gray)
        lap("binarize")
        outer = self.extractor.extract_outer(binary)
        lap("extract")
        # length_filter_steps's test, without its array round trip: one comparison per contour
        lo, hi = self._points_range
        kept = [c for c in outer if lo <= len(c.points) <= hi]
        polygons = self.approximator.approximate_many(kept)
        if not isinstance(polygons, PolygonBatch):
            # a plugin's plain list: drop what is not a polygon, pack once for the vectorized steps
            polygons = PolygonBatch.from_list([p for p in polygons if len(p) >= 3])
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
                # Centres and areas of every polygon, then the hits' rows: cheaper than gathering
                # the hits' vertices into a batch of their own first (most polygons are hits).
                centres, areas = centroids(polygons, on_zero_area="nan", return_areas=True)
                if len(hit) < len(polygons):
                    centres, areas = centres[hit], areas[hit]
                if self.bands is not None:
                    centres = self.bands.to_full(centres)
                cells = cal.grid.assign(centres)
                flat = cells[:, 0] * cols + cells[:, 1]  # negative off the grid
                # idx: the hits still taken for their cell's symbol, narrowed by each test below
                idx = np.flatnonzero(flat >= 0)
                # A fixed camera sees each cell's symbol at one size. Light and focus scale every
                # symbol alike, so the frame's median ratio is divided out; what remains is a
                # symbol grown or shrunk on its own: partly hidden, or not the symbol at all.
                ratio = areas[idx] / self._cell_area_flat[flat[idx]]
                idx = idx[np.abs(np.log(ratio)) < self._log_area_tolerance]
                # ... and at one place: an outline that strays from its cell's reference outline
                # more than light and focus make it is partly hidden.
                if len(idx):
                    picked = hit[idx]
                    # the checked outlines' samples are rows of the descriptors' (resample_complex
                    # remembers them with the batch), so no batch of the checked outlines is made
                    z = resample_complex(polygons, SAMPLES)[picked]
                    deviation, shift = samples_deviation(z.real, z.imag, self._band_distance_map)
                    straight = ~(deviation > cal.outline_tolerance_px)
                    # ... and one that left out a piece of its cell's reference outline is too
                    # (asked only of the outlines the deviation kept: a partly hidden symbol often
                    # fails both, and the second test's cost is per such symbol)
                    if not straight.all():
                        idx, picked, shift = idx[straight], picked[straight], shift[straight]
                    if len(idx):
                        cell = flat[idx]
                        hidden = hidden_piece(_Picked(polygons, picked), shift,
                                              self._ref_planes[cell].transpose(0, 2, 1),
                                              self._inward_planes[cell].transpose(0, 2, 1),
                                              self.allowance[cell], binary)
                        if hidden.any():
                            idx = idx[~hidden]
                found.ravel()[flat[idx]] = True
                ok = np.zeros(len(hit), bool)
                ok[idx] = True
                matched, candidates = centres[ok], centres[~ok]
        else:
            lap("describe")
        if self._edge_x is not None and not found.all():
            # the cells called occupied whose symbol's edge still shows all around in the grey image
            missing = np.flatnonzero(~found.ravel())
            whole = missing[edges_intact(gray, self._edge_x[missing], self._edge_y[missing],
                                         self._edge_factors[missing])]
            if len(whole):
                found.ravel()[whole] = True
                matched = np.concatenate([matched, self._cell_centres[whole]])
        lap("match")
        timings["total"] = (time.perf_counter() - t0) * 1e3
        return CellDetection(~found, int(found.sum()), matched, candidates, timings, gray.shape)

    def __call__(self, image: Any) -> Detection:
        """The whole detection: :meth:`find_cells`, then the occupancy image and the obstacles."""
        cal = self.calibration
        cells = self.find_cells(image)
        timings = {k: v for k, v in cells.timings_ms.items() if k != "total"}
        t = time.perf_counter()
        occupancy = self.mapper.occupancy_image(cal.grid, cells.occupied, cells.image_shape)
        now = time.perf_counter()
        timings["map"] = (now - t) * 1e3
        obstacles = find_obstacles(occupancy, cells.occupied, cal.grid, to_world=cal.pixels_to_world)
        timings["obstacles"] = (time.perf_counter() - now) * 1e3
        timings["total"] = cells.timings_ms["total"] + timings["map"] + timings["obstacles"]
        return Detection(cal, cells.occupied, cells.symbols_found, cells.matched_centres_px, occupancy,
                         obstacles, timings, self.stage_names, cells.candidates_px)


class _Picked(collections.abc.Sequence):
    """The outlines ``batch[i]`` for ``i`` in ``indices``, looked up only when asked for:
    :func:`~sbplan.detection.outline_checks.hidden_piece` reads a handful of them per frame, if any."""

    __slots__ = ("batch", "indices")

    def __init__(self, batch: PolygonBatch, indices: np.ndarray):
        self.batch, self.indices = batch, indices

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self.batch[int(j)] for j in self.indices[i]]
        return self.batch[int(self.indices[i])]


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
