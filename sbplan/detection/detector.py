"""Detection (paper section 4): which cells are occupied, and the obstacles they form.

The hot path: binarize -> extract -> length filter -> approximate -> describe and match ->
assign to cells -> occupancy image -> obstacles. :class:`Detector` does the per-calibration work
once (stages, reference descriptors, thresholds), so a stream of frames pays only for the image.
"""

from __future__ import annotations

import collections.abc
import functools
import logging
import os
import time
from dataclasses import dataclass, fields, replace
from typing import Any, Unpack

import numpy as np

from ..contracts import (Binarizer, ContourApproximator, ContourExtractor, DescriptorMatcher, FootprintRefiner,
                         OccupancyMapper,
                         StageChoices, array_of, call_stage, describe_value, stage_failure)
from ..errors import CameraMotionError, ContourError, DetectionError, NoFloorError
from ..imageio import ImageInput, as_gray, load_image
from ..polygons import PolygonBatch, centroids, resample_closed, resample_complex, signed_areas
from .bands import RowBands
from .calibration.file import Calibration, load_calibration
from .calibration.shapes import length_filter_steps
from .obstacles import obstacles_from_outlines
from .outline_checks import (EDGE_DEPTH_PX, EDGE_SAMPLES, EDGE_UNPROBED, scratch_points, INNER_MARGIN_PX, NEAR_HIDDEN_PX, SAMPLES, edge_factors, edge_kept,
                             edge_probes, hidden_and_near, intact_edges, reference_samples, samples_deviation,
                             ink_piece_hidden, repaired_piece_hidden, scratches_repaired,
                             signed_distance_map)
from .registration import MIN_SYMBOLS, CameraMotion, apply, centre_window, grey_centres, refine, register_pairs
from .result import CellDetection, Detection
from .working import WorkScale

log = logging.getLogger(__name__)

#: Row bands reach this many symbol sizes (and at least BAND_MARGIN_PX) above and below the
#: reference symbols: room for defocus and small camera shake.
BAND_MARGIN = 0.25
BAND_MARGIN_PX = 6.0
#: Bands are used when they cover at most this fraction of the frame's rows.
BANDS_WORTH_IT = 0.8
#: Rows a registered symbol must keep from its band's edges; closer, the frame is done again with
#: bands laid out for the registered pose (a camera that moved more than the margin since the last frame).
BAND_SPARE_PX = 2.0
#: Cells called occupied whose scratches are looked for in one frame, at most, as a share of the
#: grid's cells (a frame with more broken symbols has obstacles, not wear). A share, not a count:
#: a fixed 24 let wear break more symbols than that on a 16 x 12 grid, and none was repaired.
SCRATCH_SHARE = 0.5
#: Cells whose edge is broken at more than this share of its points are not looked at for scratches
#: (on the suite's worn floors scratched symbols broke at most 11 % of their points; 90 % of the
#: occupied cells whose edge broke, more than 15 %).
SCRATCH_BROKEN_SHARE = 0.25
#: A Detector logs the camera-movement warning once while the movement lasts, and again after this
#: many seconds.
WARN_REPEAT_S = 60.0
#: With symbols worked on reduced, a repaired symbol's allowances grow by this much (working pixels).
REPAIR_MARGIN_WORK_PX = 0.5
#: Symbols whose grey-level centres refine the registration (spread over the grid): 24 pin it to
#: about 0.05 px on the renderer's scenes at half the cost of all 50.
REGISTRATION_SYMBOLS = 24
#: find_cells_local gives way to find_cells when its crops would cover more than this share of the
#: frame (a camera bump, a change everywhere): the whole frame then costs less, and is registered.
LOCAL_SHARE = 0.5
#: What a cell's checks read around its symbol's bounding box, in symbol sizes and at least
#: LOCAL_WINDOW_PX pixels: the outline checks stay within the outline tolerance (about 3 px), the
#: edge probes within EDGE_DEPTH_PX, the scratch repair's window within 9 px.
LOCAL_WINDOW = 0.25
LOCAL_WINDOW_PX = 12.0
#: The edge check may rescue at most as many cells as the matcher found symbols (or this many, on a
#: mostly covered floor): more, and it would be deciding the cells alone.
RESCUE_MIN = 4


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

    def __init__(self, calibration: Calibration, *, binarizer: str | Binarizer | None = None,
                 extractor: str | ContourExtractor | None = None, approximator: str | ContourApproximator | None = None,
                 matcher: str | DescriptorMatcher | None = None, mapper: str | OccupancyMapper | None = None,
                 footprint: str | FootprintRefiner | None = None, row_bands: bool = True,
                 register: bool = True):
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
        self.footprint = cal.stage("footprint", footprint)
        # the footprint's per-calibration work; a stage that cannot use this calibration (an old
        # file) hands over to its fallback (pixels -> cells)
        self._footprint_data = self.footprint.prepare(cal)
        if self._footprint_data is None and getattr(self.footprint, "fallback", None):
            self.footprint = cal.stage("footprint", self.footprint.fallback)
            self._footprint_data = self.footprint.prepare(cal)
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
        # (the margin is for the binary image's pixels: in frame pixels it grows with the working factor)
        self.allowance = np.broadcast_to(tol, self.ref_points.shape[:2]) + INNER_MARGIN_PX * cal.work_scale
        # Symbols only appear in the rows where the reference showed them, moved as the camera
        # moved; when those rows are a clear part of the frame, the per-pixel work is limited to
        # them (sbplan.detection.bands), laid out for the camera's last known pose (self._bands_for).
        self._row_bands = bool(row_bands and cal.symbol_polygons)
        # frames are reduced by the calibration's working factor before their contours are traced
        # (sbplan.detection.working); bands, binary image and contours are in working pixels
        self.work = WorkScale(cal.work_scale, cal.image_shape)
        # find_cells_local's (reach, step): how far the binarizer's mask looks, in working pixels,
        # and the crop alignment it needs; None when it promises nothing or the working image is
        # not made of whole steps (then every changed frame is detected whole)
        locality = getattr(self.binarizer, "locality", None)
        reach_step = locality() if locality is not None else None
        wh, ww = self.work.work_shape
        self._locality = None if reach_step is None or wh % int(reach_step[1]) or ww % int(reach_step[1]) \
            else (int(reach_step[0]), int(reach_step[1]))
        self._symbol_size = float(np.sqrt(np.median(areas))) if len(areas) else 0.0
        self._band_margin = max(BAND_MARGIN_PX, BAND_MARGIN * self._symbol_size) if len(areas) else 0.0
        # each symbol's bounding box corners, whose rows the bands must hold (cell, 4 corners, xy)
        self._symbol_corners = np.array([[[p[:, 0].min(), p[:, 1].min()], [p[:, 0].max(), p[:, 1].min()],
                                          [p[:, 0].min(), p[:, 1].max()], [p[:, 0].max(), p[:, 1].max()]]
                                         for p in cal.symbol_polygons]).reshape(-1, 4, 2)
        self._bands_cache: tuple[np.ndarray, RowBands | None] | None = None
        self.bands: RowBands | None = self._bands_for(np.eye(3))
        # registration: the camera's movement since calibration, estimated on every frame
        # (sbplan.detection.registration); the last estimate seeds the next frame's
        self.register = bool(register)
        self.motion: CameraMotion = CameraMotion.none()
        # the last frame's cells, what find_cells_local starts from (None: no frame, or it failed)
        self._last: _LastCells | None = None
        self._kept_reads: np.ndarray | None = None
        self._windows_cache: tuple[CameraMotion, np.ndarray] | None = None
        self._warned_at: float | None = None  # time.monotonic() of the last movement warning logged
        # what the frames' grey-level centres are compared with, by flat cell number
        self._registration_centres = (cal.registration_centres_px if cal.registration_centres_px is not None
                                      else cal.grid.centres_px).reshape(-1, 2)
        self._centre_window = (centre_window([self.work.to_work(p) for p in cal.symbol_polygons])
                               if cal.symbol_polygons else 0)
        # the length filter's bounds, checked once (length_filter raises on bad ones)
        length_filter_steps([], cal.symbol_points_range)
        self._points_range = (float(cal.symbol_points_range[0]), float(cal.symbol_points_range[1]))
        self._inward_planes = np.ascontiguousarray(self.inward.transpose(0, 2, 1))
        # A cell the outline checks call occupied is free after all when the grey image still shows
        # its symbol's edge all around (sbplan.detection.outline_checks.edges_intact): where each reference
        # outline is read, and the step the reference showed there. Old calibrations have none.
        n_cells = len(cal.symbol_polygons)
        self._edge_x: np.ndarray | None = None  # None: no edge check
        self._edge_y = self._edge_factors = np.zeros((0, EDGE_SAMPLES))
        if cal.edge_contrast is not None and np.shape(cal.edge_contrast) == (n_cells, EDGE_SAMPLES) and n_cells:
            # (outlines traced in a reduced image lie up to a reduced pixel inside the ink's edge:
            # the probes reach as much farther)
            self._edge_x, self._edge_y = edge_probes(cal.symbol_polygons, EDGE_DEPTH_PX * cal.work_scale)
            self._edge_xy = np.stack([self._edge_x, self._edge_y], axis=-1).astype(np.float64)
            self._edge_factors = edge_factors(cal.edge_contrast)
            # how many edge points in a row a scratch may break, per cell (its points' spacing)
            self._scratch_points, self._break_gap = scratch_points(cal.symbol_polygons)
            self._cell_centres = centroids(cal.symbol_polygons)
        self.stage_names = {"binarizer": self.binarizer.name, "extractor": self.extractor.name,
                            "approximator": self.approximator.name, "matcher": self.matcher.name,
                            "mapper": self.mapper.name, "footprint": self.footprint.name}
        log.debug("detector: %s; row bands %s, registration %s",
                  ", ".join(f"{k} {v}" for k, v in self.stage_names.items()),
                  "on" if self.bands is not None else "off", "on" if self.register else "off",
                  extra={"data": {"stages": self.stage_names}})

    def _bands_for(self, matrix: np.ndarray) -> RowBands | None:
        """The row bands around the symbols as a camera moved by ``matrix`` (calibration -> frame)
        shows them, or None for whole frames; the last ones are kept while the pose stays within
        a pixel of theirs."""
        if not self._row_bands:
            return None
        cached = self._bands_cache
        if cached is not None and np.abs(apply(cached[0], self._symbol_corners[:, 0]) -
                                         apply(matrix, self._symbol_corners[:, 0])).max() < 1.0:
            return cached[1]
        corners = self.work.to_work(apply(matrix, self._symbol_corners))
        around = RowBands.around(corners, self.work.work_shape, margin=self._band_margin / self.work.factor)
        bands = around if around.fraction <= BANDS_WORTH_IT else None
        self._bands_cache = (matrix, bands)
        return bands

    def _bands_hold(self, bands: RowBands | None, motion: CameraMotion) -> bool:
        """Do ``bands`` hold every symbol's rows, with a few rows to spare, where ``motion`` puts them?"""
        if bands is None:
            return True
        y = self.work.to_work(apply(motion.matrix, self._symbol_corners))[..., 1]
        lo, hi = y.min(axis=1) - BAND_SPARE_PX, y.max(axis=1) + BAND_SPARE_PX
        band = np.searchsorted(bands.starts, lo, side="right") - 1
        ok = band >= 0
        return bool(ok.all() and (hi < bands.stops[band]).all() and (lo >= bands.starts[band]).all())

    def find_cells(self, image: ImageInput) -> CellDetection:
        """Image in -> occupied cells out: the pipeline up to the mapper, for callers that need
        only the cells (and what :meth:`__call__` builds on).

        The frame is first registered to the calibration (:mod:`sbplan.detection.registration`): the
        camera's movement is estimated from the symbols the matcher found, and every check after
        that reads the frame where the movement puts each cell. Pixel coordinates in the result
        are the calibration's.

        Raises
        ------
        DetectionError
            The image's size differs from the calibration's.
        CameraMotionError
            The camera's movement since calibration cannot be estimated or is too large.
        """
        cal = self.calibration
        lap = _Laps()
        timings, t0 = lap.timings, lap.t0
        gray = as_gray(load_image(image) if isinstance(image, (str, os.PathLike)) else image, name="image")
        if gray.shape != tuple(cal.image_shape):
            raise DetectionError(
                f"image is {gray.shape[1]}x{gray.shape[0]} but the calibration is for "
                f"{cal.image_shape[1]}x{cal.image_shape[0]}; calibrate on a reference from the same camera")
        hint = self.motion if self.register else CameraMotion.none()
        self._last = None  # (until this frame's cells are known: find_cells_local has nothing to start from)
        self._kept_reads = None
        bands = self._bands_for(hint.matrix)
        for attempt in range(2):
            frame = self._symbols(gray, bands, lap)
            try:
                motion = self._registered(gray, frame, hint, bands)
            except CameraMotionError as exc:
                if bands is None or attempt:
                    # a dead camera or a dark room is not a moved camera: say which it is
                    diagnosis = frame_diagnosis(gray)
                    if diagnosis:
                        raise NoFloorError(f"{diagnosis} ({len(frame[2])} symbols found)") from exc
                    raise
                # the symbols may have left the bands laid out for the last pose: the whole frame
                bands = None
                lap("register")
                continue
            lap("register")
            if attempt or self._bands_hold(bands, motion):
                break
            # the camera moved beyond the bands laid out for the last pose: lay them out again
            bands = self._bands_for(motion.matrix)
        self.motion = motion
        binary, polygons, hit, centres, areas, _, _ = frame
        last = _LastCells.empty(cal.grid.rows * cal.grid.cols)
        last.take(*self._accepted(polygons, hit, centres, areas, binary, bands, motion, gray=gray), centres)
        whole = self._rescue(gray, last, motion, None)
        lap("match")
        timings["total"] = (time.perf_counter() - t0) * 1e3
        # once while the camera stays moved (and again every WARN_REPEAT_S): a stream's detector
        # sees the same movement on every frame, and its log is not the place for 30 lines a second
        # (each result still carries the movement and its warning)
        now = time.monotonic()
        if not motion.warning:
            self._warned_at = None
        elif self._warned_at is None or now - self._warned_at >= WARN_REPEAT_S:
            self._warned_at = now
            log.warning(motion.warning, extra={"data": {"camera": motion.to_json()}})
        self._last = last
        return self._cell_detection(last, whole, timings, motion)

    def find_cells_local(self, image: ImageInput, changed: Any) -> CellDetection | None:
        """:meth:`find_cells` of a frame that differs from the last one only inside ``changed``:
        the cells near the change looked at again, the others' results and the camera's pose kept.

        The last frame's cells are kept for every cell whose symbol (and what its checks read)
        lies farther than the binarizer's reach (:meth:`~sbplan.contracts.Binarizer.locality`)
        from every changed box. The others are decided as :meth:`find_cells` decides them, under
        the last frame's pose, on crops of the frame around them: each crop is binarized,
        traced and matched alone, and the crops reach so far beyond those cells that the binary
        image is the whole frame's wherever the cells' outlines and checks read it. The edge
        check's whole-frame rules (how many cells the scratch repair looks at, rescuing no more
        cells than matching found) are applied to the whole frame, with the kept cells' results.

        Parameters
        ----------
        image : ndarray of shape (H, W) or (H, W, 3)
            The frame, of the calibration's size.
        changed : sequence of (x0, y0, x1, y1)
            Boxes of the frame (pixels, x1 and y1 excluded) outside which it equals the last frame
            this detector looked at (:meth:`find_cells` or this method).

        Returns
        -------
        CellDetection or None
            None when it cannot give what :meth:`find_cells` would: no last frame (or its
            detection failed), a binarizer that promises no locality, crops that would cover more
            than ``LOCAL_SHARE`` of the frame (a camera bump, a wide change: :meth:`find_cells`
            then costs less and registers the frame), an outline taken for a symbol that crosses
            its crop's edge, or the edge check refusing (the caller's :meth:`find_cells` then says
            why). The pose is the last frame's (``camera``); the centres are the same points as
            :meth:`find_cells` gives, possibly in another order.
        """
        last = self._last
        if last is None or self._locality is None:
            return None
        lap = _Laps()
        timings, t0 = lap.timings, lap.t0
        gray = as_gray(image, name="image")
        work, motion = self.work, self.motion
        reach, step = self._locality
        wh, ww = work.work_shape
        if gray.shape != tuple(self.calibration.image_shape):
            return None
        boxes = np.asarray(changed, dtype=np.float64).reshape(-1, 4)
        if not len(boxes):
            return None
        windows = self._windows(motion)
        # the changed boxes in working pixels, grown by how far the binarizer carries a change
        lo = np.floor(work.to_work(boxes[:, :2])) - reach - 1
        hi = np.ceil(work.to_work(boxes[:, 2:] - 1)) + reach + 2
        near = ((windows[:, None, 0] < hi[None, :, 0]) & (windows[:, None, 2] > lo[None, :, 0]) &
                (windows[:, None, 1] < hi[None, :, 1]) & (windows[:, None, 3] > lo[None, :, 1])).any(axis=1)
        crops = _merged(windows[near], reach, step, (ww, wh))
        if sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in crops) > LOCAL_SHARE * ww * wh:
            return None
        bands = self._bands_for(motion.matrix)
        whole_image = work.reduce(gray)
        new = last.copy()
        only = np.zeros(len(windows), bool)
        for x0, y0, x1, y1 in crops:
            # where the crop's binary image is the whole frame's: its inner part, and its sides on the frame's
            zone = (x0 + reach if x0 else 0, y0 + reach if y0 else 0, x1 - reach if x1 < ww else ww,
                    y1 - reach if y1 < wh else wh)
            inside = ((windows[:, 0] >= zone[0]) & (windows[:, 1] >= zone[1]) & (windows[:, 2] <= zone[2]) &
                      (windows[:, 3] <= zone[3]))
            only |= inside
            new.found[inside] = False
            # what the last frame had of these cells, and its candidates off the grid in the zone, go
            fx = work.to_work(new.hit_frame)
            gone = (inside[new.hit_cells] & (new.hit_cells >= 0)) | ((new.hit_cells < 0) & _within(fx, zone))
            new.drop(gone)
            crop_bands = _crop_bands(bands, y0, y1, x1 - x0) if bands is not None else None
            if bands is not None and crop_bands is None:
                if inside.any():
                    return None  # (cannot be: a cell's symbol rows are in the bands)
                continue  # no symbol row in this crop
            origin = np.array([x0, y0], np.float64)
            binary, polygons, hit, centres, areas, _, _ = self._symbols_in(whole_image[y0:y1, x0:x1], crop_bands, lap,
                                                                             origin)
            cells, ok, cal_centres = self._accepted(polygons, hit, centres, areas, binary, crop_bands, motion,
                                                    origin=origin, only=inside, gray=gray)
            if ok.any() and not _boxes_within(self._boxes(polygons, hit[ok], work.to_work(centres[ok]) - origin,
                                                          crop_bands) + np.tile(origin, 2), zone):
                return None  # an outline taken for a symbol crosses the crop's edge: not the whole frame's
            keep = np.flatnonzero(cells >= 0)
            keep = np.concatenate([keep[inside[cells[keep]]],
                                   np.flatnonzero((cells < 0) & _within(work.to_work(centres), zone))])
            new.take(cells[keep], ok[keep], cal_centres[keep], centres[keep])
        lap("match")
        try:
            whole = self._rescue(gray, new, motion, only)
        except DetectionError:
            return None
        lap("rescue")
        timings["total"] = (time.perf_counter() - t0) * 1e3
        self._last = new
        kept = windows[~only]
        self._kept_reads = work.to_frame(np.concatenate([kept[:, :2] - reach, kept[:, 2:] + reach], axis=1)
                                         .reshape(-1, 2, 2)).reshape(-1, 4)
        return self._cell_detection(new, whole, timings, motion)

    def kept_reads(self) -> np.ndarray | None:
        """Where the cells the last :meth:`find_cells_local` kept read the frame (their symbols'
        surroundings, grown by the binarizer's reach): boxes ``(x0, y0, x1, y1)`` in frame pixels,
        shape (k, 4). Pixels outside them decide no kept cell: the caller may take the frame it
        gave as the one those pixels were last looked at in. None after :meth:`find_cells` (every
        cell decided on that frame)."""
        return self._kept_reads

    def _windows(self, motion: CameraMotion) -> np.ndarray:
        """Each cell's symbol's bounding box grown by ``LOCAL_WINDOW`` symbol sizes where ``motion``
        puts it, ``(x0, y0, x1, y1)`` in working pixels: what its outline checks and edge check read."""
        cached = self._windows_cache
        if cached is not None and cached[0] is motion:
            return cached[1]
        corners = self.work.to_work(apply(motion.matrix, self._symbol_corners))
        margin = max(LOCAL_WINDOW * self._symbol_size, LOCAL_WINDOW_PX) / self.work.factor
        windows = np.concatenate([corners.min(axis=1) - margin, corners.max(axis=1) + margin], axis=1)
        self._windows_cache = (motion, windows)
        return windows

    def _accepted(self, polygons: PolygonBatch, hit: np.ndarray, centres: np.ndarray, areas: np.ndarray,
                  binary: np.ndarray, bands: RowBands | None, motion: CameraMotion, *,
                  origin: np.ndarray | None = None, only: np.ndarray | None = None,
                  gray: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Which of the outlines the matcher took for the symbol (``polygons[hit]``, centres and
        areas in frame pixels) are their cells' symbols, whole: the cell (flat index, -1 off the
        grid) of each, whether it passed the outline checks, and its centre in the calibration's
        pixels. The binary image and the outlines are in working pixels, stacked by ``bands``, of
        a crop whose corner is ``origin`` (x, y) in the working image; with ``only`` (flat cells,
        bool), the outlines of other cells are not checked (not passed). With the frame ``gray``,
        a symbol that comes near the hidden-piece limit is also asked whether its grey edge
        shows all around (:data:`~sbplan.detection.outline_checks.NEAR_HIDDEN_PX`)."""
        cal, work = self.calibration, self.work
        flat = np.full(len(hit), -1, np.int64)
        ok = np.zeros(len(hit), bool)
        moved = motion.moved
        if len(hit):
            # centres in the calibration's pixels, where the cells and their reference outlines are
            centres = motion.to_calibration(centres) if moved else centres
            flat = cal.grid.assign_flat(centres)  # -1 off the grid
            # idx: the hits still taken for their cell's symbol, narrowed by each test below
            idx = np.flatnonzero(flat >= 0)
            if only is not None:
                idx = idx[only[flat[idx]]]
            # A camera sees each cell's symbol at one size (times the registered zoom). Light and
            # focus scale every symbol alike; what remains is a symbol grown or shrunk on its own:
            # partly hidden, or not the symbol at all.
            ratio = areas[idx] / (self._cell_area_flat[flat[idx]] * motion.scale ** 2)
            idx = idx[np.abs(np.log(ratio)) < self._log_area_tolerance]
            # ... and at one place: an outline that strays from its cell's reference outline
            # more than light and focus make it is partly hidden.
            if len(idx):
                picked = hit[idx]
                # the checked outlines' samples are rows of the descriptors' (resample_complex
                # remembers them with the batch), so no batch of the checked outlines is made
                z = resample_complex(polygons, SAMPLES)[picked]
                # (complex samples viewed as their (x, y) pairs: no copy)
                xy = z.view(np.float64).reshape(len(picked), SAMPLES, 2)
                if bands is not None:
                    xy = bands.to_full_outlines(xy)
                if origin is not None:
                    xy = xy + origin
                xy = work.to_frame(xy)
                if moved:
                    xy = motion.to_calibration(xy)
                per_outline = xy.reshape(len(picked), SAMPLES, 2)
                deviation, shift = samples_deviation(per_outline[..., 0], per_outline[..., 1], self.distance_map)
                # the outline's shift was measured in calibration pixels; the frame's are scaled
                shift = shift * motion.scale
                straight = ~(deviation > cal.outline_tolerance_px)
                # ... and one that left out a piece of its cell's reference outline is too
                # (asked only of the outlines the deviation kept: a partly hidden symbol often
                # fails both, and the second test's cost is per such symbol)
                if not straight.all():
                    idx, picked, shift = idx[straight], picked[straight], shift[straight]
                if len(idx):
                    cell = flat[idx]
                    points, inward = self.ref_points[cell], self.inward[cell]
                    if moved:
                        points, inward = motion.to_frame(points), motion.turn(inward)
                    points = work.to_work(points)
                    if origin is not None:
                        points = points - origin
                    if bands is not None:
                        points = bands.to_stacked_outlines(points)
                    # the binary image and the outlines are in working pixels
                    allowance = self.allowance[cell] * (motion.scale / work.factor)
                    second_opinion = gray is not None and self._edge_x is not None
                    hidden, near = hidden_and_near(_Picked(polygons, picked), shift / work.factor, points, inward,
                                                   allowance, binary, within=NEAR_HIDDEN_PX if second_opinion else 0.0)
                    if gray is not None and near.any():
                        # ... and one that passed near the limit, where its grey edge is broken:
                        # a bite the binary outline's pixel phase hid
                        hidden[near] = ~self._edges_intact(gray, cell[near], motion)
                    if hidden.any():
                        idx = idx[~hidden]
            ok[idx] = True
        return flat, ok, centres

    def _rescue(self, gray: np.ndarray, last: "_LastCells", motion: CameraMotion, only: np.ndarray | None) -> np.ndarray:
        """The cells (flat indices) matching did not find whose symbol's edge the grey image still
        shows all around, but for short breaks where scratches cross it: the edge check of
        ``last``'s unmatched cells (of the ``only`` ones, the others' results kept), its per-cell
        results stored in ``last``.

        Raises
        ------
        DetectionError
            The edge check would call more cells free than matching found (the matcher does not fit).
        """
        cal = self.calibration
        if self._edge_x is None:
            return np.zeros(0, np.int64)
        todo = ~last.found if only is None else ~last.found & only
        every = slice(None) if only is None else only
        last.plain[every] = last.intact[every] = last.broken[every] = False
        last.repaired[every] = -1
        missing = np.flatnonzero(todo)
        if len(missing):
            kept, probed, cut = self._edge_reads(gray, missing, motion)
            # (the scratch repair reads a whole symbol's window, and a partly seen symbol is no
            # proof that the matcher does not fit: those cells are neither broken nor plain)
            whole = np.ones(len(missing), bool) if cut is None else ~np.asarray(cut.any(axis=1))
            intact = intact_edges(kept, max_break=self._scratch_points[missing], gap=self._break_gap[missing],
                                  probed=probed)
            last.intact[missing] = intact
            # ... or shows it once the thin scratches across it are painted over (wear), asked of
            # a few cells only: an obstacle over a symbol breaks much of its edge, scratches a few
            # points, and a floor that is mostly occupied is not worn symbols
            last.broken[missing] = ~intact & ((~kept).mean(axis=1) <= SCRATCH_BROKEN_SHARE) & whole
            # (the symbols whose edge shows at every point: what a matcher that does not fit the
            # floor leaves unmatched; scratched symbols break their edge here and there)
            last.plain[missing] = kept.all(axis=1) & whole
        broken = np.flatnonzero(last.broken)
        rescued = last.intact
        if 0 < len(broken) <= SCRATCH_SHARE * len(last.found):
            # (a cell's repair reads its own window only: one kept from the last frame stands)
            need = broken[last.repaired[broken] < 0]
            if len(need):
                ex, ey = self._probes(need, motion)
                outlines = [cal.symbol_polygons[c] for c in need]
                holes = None if cal.symbol_holes is None else [cal.symbol_holes[c] for c in need]
                if motion.moved:
                    outlines = [motion.to_frame(o) for o in outlines]
                    if holes is not None:
                        holes = [[motion.to_frame(h) for h in hs] for hs in holes]
                last.repaired[need] = scratches_repaired(gray, outlines, ex, ey, self._edge_factors[need],
                                                         max_break=self._scratch_points[need],
                                                         gap=self._break_gap[need], holes=holes,
                                                         piece_hidden=self._piece_hidden(need, motion, gray))
            rescued = rescued | (last.broken & (last.repaired == 1))
        matched_count = int(last.found.sum())
        plain = int(last.plain.sum())
        if plain > max(matched_count, RESCUE_MIN):
            # The edge check rescues symbols the binary image spoiled; it does not find them.
            # Deciding more cells than matching did, it would be answering alone. (Only the
            # symbols whose edge is unbroken count: on a worn floor with many objects the
            # scratched symbols it calls whole can outnumber the ones matched.)
            raise DetectionError(
                f"the matcher ({self.matcher.name}) took only {matched_count} of {cal.symbols_expected} symbols "
                f"for the symbol, and the grey-level edge check would call {plain} more free: the matcher or "
                "its threshold does not fit this floor (a broken or swapped matcher, a calibration made with "
                "another one, or symbols worn past recognition); recalibrate with the matcher you detect with")
        return np.flatnonzero(rescued)

    def _edges_intact(self, gray: np.ndarray, cells: np.ndarray, motion: CameraMotion) -> np.ndarray:
        """Whether the grey edge of each of ``cells`` (flat indices) shows all around, as the edge
        check of :meth:`_rescue` reads it (short breaks forgiven, points out of view not counted)."""
        kept, probed, _ = self._edge_reads(gray, cells, motion)
        # (an edge kept at every point is intact whatever the rules for breaks: most symbols)
        intact = np.asarray(kept.all(axis=1))  # (n,) bool: the stubs allow a scalar
        if not intact.all():
            some = np.flatnonzero(~intact)
            intact[some] = intact_edges(kept[some], max_break=self._scratch_points[cells[some]],
                                        gap=self._break_gap[cells[some]], probed=probed[some])
        return intact

    def _edge_reads(self, gray: np.ndarray, cells: np.ndarray, motion: CameraMotion
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The edge check's reading of ``cells`` (flat indices) in the frame ``gray``: whether each
        point kept its step (n, S), which points are probed (n, S), and the points out of view
        (n, S), or None when all are in view. Points out of view count as kept and not probed."""
        ex, ey = self._probes(cells, motion)
        factors = self._edge_factors[cells]
        kept = edge_kept(gray, ex, ey, factors)
        probed = factors < EDGE_UNPROBED
        # A camera that moved can push a symbol at the frame's edge partly out of view: its
        # outline no longer matches, and the frame has nothing to say where it left. Such a
        # cell is judged by the part of its edge in view, when that is most of it.
        cut = _out_of_view(ex, ey, gray.shape) if motion.moved else None
        if cut is not None:
            kept, probed = kept | cut, probed & ~cut
        return kept, probed, cut

    def _probes(self, cells: np.ndarray, motion: CameraMotion) -> tuple[np.ndarray, np.ndarray]:
        """The edge probes ``(x, y)`` of ``cells`` (flat indices) where ``motion`` puts them, (n, EDGE_SAMPLES) each."""
        if motion.moved:
            q = motion.to_frame(self._edge_xy[cells])
            return q[..., 0].astype(np.float32), q[..., 1].astype(np.float32)
        return self._edge_x[cells], self._edge_y[cells]  # type: ignore[index]

    def _cell_detection(self, last: "_LastCells", whole: np.ndarray, timings: dict[str, float],
                        motion: CameraMotion) -> CellDetection:
        """The result of the cells ``last`` holds, with the cells ``whole`` rescued by the edge check."""
        found = last.found.copy()
        found[whole] = True
        matched = last.hit_centres[last.hit_ok]
        if len(whole):
            matched = np.concatenate([matched, self._cell_centres[whole]])
        rows, cols = self.calibration.grid.shape
        return CellDetection(~found.reshape(rows, cols), int(last.found.sum()), matched,
                             last.hit_centres[~last.hit_ok], timings, self.work.shape, motion,
                             symbols_rescued=len(whole))

    def _piece_hidden(self, cells: np.ndarray, motion: CameraMotion, gray: np.ndarray):
        """The whole-symbol test :func:`scratches_repaired` asks of the repaired symbols of
        ``cells`` (flat indices) in the frame ``gray``: the outline checks' inward test
        (:func:`ink_piece_hidden`) on the repaired window as the frame's binary image would show
        it, with the reference points where ``motion`` puts them.

        Symbols traced at the frame's resolution: the window thresholded halfway from its ink to
        its floor (:func:`repaired_piece_hidden`). Symbols worked on in a reduced image
        (:mod:`~sbplan.detection.working`): their outlines and allowances come from the
        binarizer's ink there, and read at the frame's resolution every scratched symbol, and the
        reference's own, lost a piece (4K, 10 x 5 cells). The window is then tested as a matched
        symbol is: pasted into the frame's surroundings as far as the binarizer's local level
        reaches, reduced and binarized (the frame's ink with the scratches painted over), with its
        outline's common shift taken out. (At the frame's resolution the binarizer's ink, fatter
        than the halfway threshold's, let an object over 6 % of a flag's tip pass.)"""
        work, f = self.work, self.work.factor
        wh, ww = work.work_shape
        # how far (working pixels) the binarizer's mask looks, and the crop alignment it needs;
        # without a promise, the whole frame is its surroundings
        reach, step = self._locality if self._locality is not None else (max(wh, ww), 1)

        def hidden(i: int, repaired: np.ndarray, origin: tuple[int, int], level: float) -> bool:
            cell = int(cells[i])
            points, inward = self.ref_points[cell], self.inward[cell]
            if motion.moved:
                points, inward = motion.to_frame(points), motion.turn(inward)
            if f == 1:
                return repaired_piece_hidden(repaired, origin, points, inward,
                                             self.allowance[cell] * motion.scale, level)
            x0, y0 = origin
            h, w = repaired.shape
            # the window's whole working pixels, and the crop around them the binarizer needs
            u0, v0, u1, v1 = -(-x0 // f), -(-y0 // f), (x0 + w) // f, (y0 + h) // f
            if u1 - u0 < 3 or v1 - v0 < 3:
                return False
            cu0, cv0 = max(0, u0 - reach) // step * step, max(0, v0 - reach) // step * step
            cu1, cv1 = min(ww, -(-(u1 + reach) // step) * step), min(wh, -(-(v1 + reach) // step) * step)
            canvas = gray[cv0 * f:cv1 * f, cu0 * f:cu1 * f].copy()
            canvas[y0 - cv0 * f:y0 - cv0 * f + h, x0 - cu0 * f:x0 - cu0 * f + w] = repaired
            small = work.reduce_part(canvas)
            ink = call_stage(self.binarizer, "binarize", small, returns=_mask_of(small.shape))
            ink = np.asarray(ink)[v0 - cv0:v1 - cv0, u0 - cu0:u1 - cu0]
            corner = np.array([u0, v0], np.float64)

            def common_shift(outline: np.ndarray) -> float:
                # the ink outline's shift against the reference outline, as _accepted measures a
                # matched symbol's (in the calibration's pixels, then the working image's)
                xy = work.to_frame(resample_closed(outline, SAMPLES) + corner)
                if motion.moved:
                    xy = motion.to_calibration(xy)
                _, shift = samples_deviation(xy[None, :, 0], xy[None, :, 1], self.distance_map)
                return float(shift[0]) * motion.scale / f

            # (the paint reaches the reference outline, which runs through the centres of the
            # working image's boundary pixels: where a scratch crossed the edge, the repaired ink
            # may end up to half a working pixel short of the edge the allowances were measured on)
            return ink_piece_hidden(ink, (u0, v0), work.to_work(points), inward,
                                    self.allowance[cell] * motion.scale / f + REPAIR_MARGIN_WORK_PX,
                                    common_shift=common_shift)
        return hidden

    def _symbols(self, gray: np.ndarray, bands: RowBands | None, lap) -> tuple:
        """Binarize, extract, approximate and match one frame (at the working resolution): the
        binary image, the polygons, the indices of those the matcher took for the symbol, their
        centres and areas in the frame's pixels, their centres in working pixels, and the working
        image."""
        return self._symbols_in(self.work.reduce(gray), bands, lap)

    def _symbols_in(self, image: np.ndarray, bands: RowBands | None, lap, origin: np.ndarray | None = None) -> tuple:
        """:meth:`_symbols` of a working image, or of a crop of one whose corner is ``origin``
        (x, y) (the centres are then the whole frame's)."""
        # every stage is called through call_stage: a plugin's exception or broken result is a
        # StageError naming it, checked by one comparison (or one sum) per call
        if bands is not None:
            binary = call_stage(self.binarizer, "binarize_bands", image, bands,
                                returns=_mask_of(bands.stacked_shape))
        else:
            binary = call_stage(self.binarizer, "binarize", image, returns=_mask_of(image.shape))
        lap("binarize")
        outer = call_stage(self.extractor, "extract_outer", binary, returns=_sequence)
        lap("extract")
        # length_filter_steps's test, without its array round trip: one comparison per contour
        lo, hi = self._points_range
        try:
            kept = [c for c in outer if lo <= len(c.points) <= hi]
        except (AttributeError, TypeError):
            raise stage_failure(self.extractor, "broke its contract: extract_outer() returned items that are "
                                                "not Contours") from None
        polygons = call_stage(self.approximator, "approximate_many", kept, returns=_sequence)
        if not isinstance(polygons, PolygonBatch):
            # a plugin's plain list: drop what is not a polygon, pack once for the vectorized steps
            try:
                polygons = PolygonBatch.from_list([p for p in polygons if len(p) >= 3])
            except (ContourError, TypeError, ValueError) as exc:
                raise stage_failure(self.approximator, "broke its contract: approximate_many() returned outlines "
                                                       f"that are not (N, 2) finite points ({exc})") from None
        lap("approximate")
        hit = np.zeros(0, np.int64)
        centres, areas = np.zeros((0, 2)), np.zeros(0)
        if len(polygons):
            n = len(polygons)
            desc = call_stage(self.matcher, "describe_many", polygons,
                              returns=array_of((n, len(self.descriptor)), finite=True))
            d = call_stage(self.matcher, "distance_matrix", desc, self.descriptor[None, :],
                           returns=array_of((n, 1), finite=True))[:, 0]
            hit = np.flatnonzero(d < self.threshold)
            if len(hit):
                centres, areas = centroids(polygons, on_zero_area="nan", return_areas=True)
                if len(hit) < len(polygons):
                    centres, areas = centres[hit], areas[hit]
                if bands is not None:
                    centres = bands.to_full(centres)
                if origin is not None:
                    centres = centres + origin
        lap("describe")
        return binary, polygons, hit, self.work.to_frame(centres), areas * self.work.area, centres, image

    def _registered(self, gray: np.ndarray, frame: tuple, hint: CameraMotion, bands: RowBands | None) -> CameraMotion:
        """The camera's movement since calibration, from the symbols of ``frame``: a coarse fit on
        the outlines' centres, then the inliers' grey-level centres (sub-pixel) refitted."""
        if not self.register:
            return CameraMotion.none()
        binary, polygons, hit, centres, areas, work_centres, image = frame
        cal = self.calibration
        # (the frame's texture is compared at a quarter of the calibration's size: the working
        # image gets there with fewer halvings)
        coarse, cells = register_pairs(centres, cal.grid, cal.image_shape, hint=hint.matrix,
                                       reference_thumbnail=cal.reference_thumbnail, frame=image)
        take = np.flatnonzero(cells >= 0)
        if coarse.model == "assumed" or len(take) < MIN_SYMBOLS:
            return coarse
        if len(take) > REGISTRATION_SYMBOLS:
            # evenly over the grid's cells: a spread-out set pins rotation and scale
            take = take[np.argsort(cells[take], kind="stable")]
            take = take[_evenly(len(take), REGISTRATION_SYMBOLS)]
        # sub-pixel centres, measured in the working image as calibration measured the reference's
        boxes = self._boxes(polygons, hit[take], work_centres[take], bands)
        fine = self.work.to_frame(grey_centres(image, boxes, self._centre_window))
        return refine(fine, cells[take], self._registration_centres, cal.grid, cal.image_shape, coarse)

    def _boxes(self, polygons: PolygonBatch, picked: np.ndarray, centres: np.ndarray,
               bands: RowBands | None) -> np.ndarray:
        """Bounding boxes ``(x0, y0, x1, y1)`` in working pixels of the polygons ``picked``, whose
        centres in working pixels are ``centres``."""
        boxes = polygons.boxes(picked)
        if bands is not None:
            # an outline lies inside one band: all its rows move by that band's shift
            dy = centres[:, 1] - bands.to_stacked(centres)[:, 1]
            boxes[:, 1] += dy
            boxes[:, 3] += dy
        return boxes

    def __call__(self, image: ImageInput) -> Detection:
        """The whole detection: :meth:`find_cells`, then the occupancy image, the obstacles'
        footprints (the footprint stage) and the obstacles."""
        cal = self.calibration
        t0 = time.perf_counter()
        gray = as_gray(load_image(image) if isinstance(image, (str, os.PathLike)) else image, name="image")
        cells = self.find_cells(gray)
        timings = {k: v for k, v in cells.timings_ms.items() if k != "total"}
        t = time.perf_counter()
        occupancy = call_stage(self.mapper, "occupancy_image", cal.grid, cells.occupied, cells.image_shape,
                               returns=array_of(tuple(cells.image_shape), kinds="u"))
        now = time.perf_counter()
        timings["map"] = (now - t) * 1e3
        obstacles = self.obstacles(gray, cells.occupied, occupancy, cells.camera, timings)
        timings["obstacles"] = (time.perf_counter() - now) * 1e3 - timings["footprint"]
        timings["total"] = (time.perf_counter() - t0) * 1e3
        if log.isEnabledFor(logging.DEBUG):
            log.debug("%d/%d symbols, %d occupied cells, %d obstacles in %.1f ms (%s)", cells.symbols_found,
                      cal.symbols_expected, int(cells.occupied.sum()), len(obstacles), timings["total"],
                      ", ".join(f"{k} {v:.1f}" for k, v in timings.items() if k != "total"),
                      extra={"data": {"timings_ms": timings, "symbols_found": cells.symbols_found,
                                      "occupied_cells": int(cells.occupied.sum()), "obstacles": len(obstacles)}})
        return Detection(cal, cells.occupied, cells.symbols_found, cells.matched_centres_px, occupancy,
                         obstacles, timings, self.stage_names, cells.candidates_px, cells.camera,
                         symbols_rescued=cells.symbols_rescued)

    def obstacles(self, gray: np.ndarray, occupied: np.ndarray, occupancy: np.ndarray, camera: CameraMotion,
                  timings: dict[str, float] | None = None) -> list:
        """The obstacles of occupied cells on a frame: each one's outline by the footprint stage,
        then its cells, MAR and parts (:func:`~sbplan.detection.obstacles.obstacles_from_outlines`).

        Parameters
        ----------
        gray : ndarray of shape (H, W), uint8
            The frame the cells were decided on.
        occupied : ndarray of shape (rows, cols), bool
        occupancy : ndarray of shape (H, W), uint8
            The mapper's occupancy image of ``occupied``.
        camera : CameraMotion
            The frame's movement since calibration.
        timings : dict, optional
            Gets the footprint stage's milliseconds under ``"footprint"``.
        """
        cal = self.calibration
        t = time.perf_counter()
        outlines = call_stage(self.footprint, "outlines", gray, occupied, occupancy, cal, camera, self._footprint_data,
                              returns=_outlines_check)
        if timings is not None:
            timings["footprint"] = (time.perf_counter() - t) * 1e3
        return obstacles_from_outlines(outlines, occupied, cal.grid, to_world=cal.pixels_to_world,
                                       to_pixels=cal.world_to_pixels)


#: A cell whose symbol the camera's movement put partly out of the frame is judged by the edge
#: points in view when at least this share of them is (else it stays occupied: unseen is not free).
IN_VIEW_SHARE = 0.5


@functools.lru_cache(maxsize=64)
def _evenly(n: int, k: int) -> np.ndarray:
    """``k`` indices spread evenly over ``0 .. n - 1`` (both ends included), read-only."""
    out = np.linspace(0, n - 1, k).round().astype(np.int64)
    out.flags.writeable = False
    return out


def _out_of_view(x: np.ndarray, y: np.ndarray, shape: tuple[int, int]) -> np.ndarray | None:
    """Of edge probes ``x``, ``y`` (n, 2, S) in frame pixels, the points (n, S) whose inner or outer
    probe lies outside a frame of ``shape`` (H, W) (with the pixel that bilinear reading needs), on
    outlines that keep at least :data:`IN_VIEW_SHARE` of their points in view; None when every
    point is in view."""
    h, w = shape
    if x.size == 0 or (x.min() >= 1 and y.min() >= 1 and x.max() <= w - 2 and y.max() <= h - 2):
        return None
    out = ((x < 1) | (y < 1) | (x > w - 2) | (y > h - 2)).any(axis=1)
    out &= (out.mean(axis=1) <= 1.0 - IN_VIEW_SHARE)[:, None]
    return out if out.any() else None


def _outlines_check(v: Any) -> str | None:
    """The footprint stage's contract: a list of (K >= 3, 2) arrays."""
    if not isinstance(v, list):
        return f"{describe_value(v)}, expected a list of (K, 2) outlines"
    for i, o in enumerate(v):
        a = np.asarray(o) if not isinstance(o, np.ndarray) else o
        if a.ndim != 2 or a.shape[1] != 2 or len(a) < 3 or a.dtype.kind not in "iuf" or not np.isfinite(a).all():
            return f"outline {i} as {describe_value(a)}, expected finite (K >= 3, 2) points"
    return None


def _mask_of(shape: tuple[int, int]):
    """The binarizer's contract: a mask of ``shape`` (bool, or 0/1 integers)."""
    def check(v: Any) -> str | None:
        if isinstance(v, np.ndarray) and v.shape == shape and v.dtype.kind in "bui":
            return None
        return f"{describe_value(v)}, expected a mask of shape {shape}"
    return check


def _sequence(v: Any) -> str | None:
    if isinstance(v, (list, tuple, PolygonBatch)):
        return None
    return f"{describe_value(v)}, expected a list"


def _merged(windows: np.ndarray, reach: int, step: int, size: tuple[int, int]) -> list[tuple[int, int, int, int]]:
    """Crops ``(x0, y0, x1, y1)`` holding each window with ``reach`` pixels to spare (less at the
    image's sides), corners on multiples of ``step``, inside an image of ``size`` (W, H); crops
    that overlap merged."""
    w, h = size
    lo = np.maximum(np.floor((windows[:, :2] - reach) / step) * step, 0).astype(np.int64)
    hi = np.minimum(np.ceil((windows[:, 2:] + reach) / step) * step, (w, h)).astype(np.int64)
    crops = [list(map(int, (a[0], a[1], b[0], b[1]))) for a, b in zip(lo, hi)]
    merged = True
    while merged:
        merged = False
        for i in range(len(crops)):
            for j in range(i + 1, len(crops)):
                a, b = crops[i], crops[j]
                if a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]:
                    crops[i] = [min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])]
                    del crops[j]
                    merged = True
                    break
            if merged:
                break
    return [(a, b, c, d) for a, b, c, d in crops]


def _within(xy: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """Which points ``(x, y)`` (N, 2) lie inside ``box`` ``(x0, y0, x1, y1)``."""
    return (xy[:, 0] >= box[0]) & (xy[:, 1] >= box[1]) & (xy[:, 0] <= box[2]) & (xy[:, 1] <= box[3])


def _boxes_within(boxes: np.ndarray, box: tuple[int, int, int, int]) -> bool:
    """Do all boxes ``(x0, y0, x1, y1)`` (N, 4) lie inside ``box`` with a pixel to spare?"""
    return bool(_within(boxes[:, :2] - 1, box).all() and _within(boxes[:, 2:] + 1, box).all())


def _crop_bands(bands: RowBands, y0: int, y1: int, width: int) -> RowBands | None:
    """The bands' rows within rows ``[y0, y1)``, for a crop of those rows ``width`` wide; None when there are none."""
    a = np.maximum(bands.starts, y0)
    b = np.minimum(bands.stops, y1)
    keep = b > a
    if not keep.any():
        return None
    return RowBands(np.stack([a[keep] - y0, b[keep] - y0], axis=1).tolist(), (y1 - y0, width))


#: A frame whose grey levels (1st to 99th percentile) span fewer than this shows no floor.
UNIFORM_LEVELS = 12
#: A frame whose 99th percentile is below this is too dark to show the symbols.
DARK_LEVEL = 40


def frame_diagnosis(gray: np.ndarray) -> str | None:
    """Why a frame may show no floor at all, for the operator, or None when it looks like a view
    (then the registration's own message stands). Only asked when registration failed."""
    step = max(1, int(np.sqrt(gray.size / 250_000)))
    sample = gray[::step, ::step]
    lo, hi = (float(v) for v in np.percentile(sample, [1, 99]))
    if hi < DARK_LEVEL:
        return (f"no floor in view: the frame is {'black' if hi < 2 else 'very dark'} (grey levels up to {hi:.0f} "
                "of 255); check the light, the lens cover and the camera's exposure, then detect again")
    if hi - lo < UNIFORM_LEVELS:
        return (f"no floor in view: the frame is almost uniform (grey levels {lo:.0f} to {hi:.0f} of 255); check the "
                "camera (lens covered, overexposed, cable), then detect again")
    s = sample.astype(np.float32)
    spread = float(s.std())
    # neighbours of a real view are alike; in sensor noise or a broken signal they are as unlike
    # as any two pixels
    jump = float(np.abs(np.diff(s, axis=1)).mean())
    if spread > 10 and jump > 0.8 * spread:
        return ("no floor in view: the frame is noise (neighbouring pixels are unrelated); the camera's signal is "
                "broken: check the camera and its cable, then detect again")
    return None


class _Laps:
    """Milliseconds per step: ``lap(name)`` adds the time since the last lap to ``timings[name]``."""

    __slots__ = ("timings", "t0", "_t")

    def __init__(self) -> None:
        self.timings: dict[str, float] = {}
        self.t0 = self._t = time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.timings[name] = self.timings.get(name, 0.0) + (now - self._t) * 1e3
        self._t = now


@dataclass(eq=False)
class _LastCells:
    """A frame's cells as :meth:`Detector.find_cells` decided them, by flat cell number, with what
    the edge check found of each: what :meth:`Detector.find_cells_local` keeps of the cells it does
    not look at again, and the outlines taken for the symbol (``hit_*``), one row each."""

    found: np.ndarray  # (n,) bool: the symbol matched and passed the outline checks
    plain: np.ndarray  # (n,) bool: not found, its edge shows at every point
    intact: np.ndarray  # (n,) bool: not found, its edge shows all around but for short breaks
    broken: np.ndarray  # (n,) bool: not found nor intact, a candidate for the scratch repair
    repaired: np.ndarray  # (n,) int8: the scratch repair's answer, -1 where it was not asked
    hit_cells: np.ndarray  # (m,) int64: the flat cell of each outline, -1 off the grid
    hit_ok: np.ndarray  # (m,) bool: taken for its cell's symbol
    hit_centres: np.ndarray  # (m, 2): (x, y), calibration pixels
    hit_frame: np.ndarray  # (m, 2): (x, y), frame pixels

    @classmethod
    def empty(cls, n: int) -> "_LastCells":
        z = np.zeros((0, 2))
        return cls(np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, bool), np.full(n, -1, np.int8),
                   np.zeros(0, np.int64), np.zeros(0, bool), z, z)

    def take(self, cells: np.ndarray, ok: np.ndarray, centres: np.ndarray, frame: np.ndarray) -> None:
        """Add outlines (their cells, whether taken, centres in calibration and frame pixels)."""
        self.found[cells[ok]] = True
        self.hit_cells = np.concatenate([self.hit_cells, cells])
        self.hit_ok = np.concatenate([self.hit_ok, ok])
        self.hit_centres = np.concatenate([self.hit_centres, centres.reshape(-1, 2)])
        self.hit_frame = np.concatenate([self.hit_frame, frame.reshape(-1, 2)])

    def drop(self, rows: np.ndarray) -> None:
        """Forget the outlines where ``rows`` (bool, one per outline) is True."""
        keep = ~rows
        self.hit_cells, self.hit_ok = self.hit_cells[keep], self.hit_ok[keep]
        self.hit_centres, self.hit_frame = self.hit_centres[keep], self.hit_frame[keep]

    def copy(self) -> "_LastCells":
        return _LastCells(*(np.array(getattr(self, f.name)) for f in fields(self)))


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


def detect(image: ImageInput, calibration: Calibration | str | os.PathLike,
           **stages: Unpack[StageChoices]) -> Detection:
    """Detect the occupied cells and obstacles of one image.

    Parameters
    ----------
    image : ndarray of shape (H, W) or (H, W, 3), or a path
        The current image, from the camera of the calibration.
    calibration : Calibration or path of a calibration JSON
    **stages : str or Stage
        ``binarizer``, ``extractor``, ``approximator``, ``matcher``, ``mapper``, ``footprint`` overrides.

    Raises
    ------
    DetectionError
        The image's size differs from the calibration's.
    """
    if not isinstance(calibration, Calibration):
        calibration = load_calibration(calibration)
    return Detector(calibration, **stages)(image)
