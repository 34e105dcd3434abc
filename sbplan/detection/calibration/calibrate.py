"""Calibration on the empty floor (paper section 2.2).

From the reference image: every contour, the length filter, polygon approximation, descriptors and
centres of area; the reference symbol (given as an image of one symbol, or inferred as the dominant
repeated shape); the grid fitted to the symbols' centres; and a match threshold derived from the
data — the distances of the true symbols against those of every other contour — instead of the
paper's a-priori 0.5.
"""

from __future__ import annotations

import logging
import os
from dataclasses import replace
from typing import Any, Callable, Unpack, cast

import cv2
import numpy as np

from ... import limits, registry
from ...contracts import (Binarizer, ContourApproximator, ContourExtractor, DescriptorMatcher, FootprintRefiner,
                          OccupancyMapper,
                          StageChoices, distances_between)
from ...errors import CalibrationError, InputError
from ...imageio import ImageInput, as_gray, load_image
from ...workspace import MAX_METRES, Workspace, load_workspace
from ..grid import Grid, fit_grid, lattice_gaps
from ..outline_checks import (EDGE_DEPTH_PX, edge_contrast, edge_probes, inner_deviations, inner_tolerance,
                              outline_deviation, reference_samples, signed_distance_map)
from ..registration import CameraMotion, centre_window, grey_centres, thumbnail
from .file import SYMBOL_WINDOW, Calibration
from ..working import WorkScale, work_factor
from .shapes import Shapes, extract_shapes
from .threshold import match_threshold

log = logging.getLogger(__name__)

#: The stages used when none is named: the fast ones (the paper's OKE and KKA are selectable).
DEFAULT_STAGES = {
    "binarizer": "background",
    "extractor": "opencv",
    "approximator": "douglas-peucker",
    "matcher": "fourier",
    "mapper": "cells",
    "footprint": "pixels",
}


def _stage_spec(stage) -> dict[str, Any]:
    return {"name": stage.name, "options": stage.config()}


def _symbol_descriptor_from_image(symbol: ImageInput, *, extractor, approximator, matcher) -> np.ndarray:
    gray = as_gray(load_image(symbol) if isinstance(symbol, (str, os.PathLike)) else symbol, name="symbol")
    # An image of one symbol on a plain ground, at any scale: one global threshold separates them
    # (a local binarizer sized for the floor's symbols would not), and the largest dark shape is it.
    h, w = gray.shape
    shapes = extract_shapes(gray, binarizer=registry.binarizer("otsu"), extractor=extractor,
                            approximator=approximator, matcher=matcher, points_range=(8, 4 * (h + w)))
    if not shapes.polygons:
        raise CalibrationError("symbol image: no dark shape found in it")
    return shapes.descriptors[int(np.argmax(shapes.areas))]


def update_calibration(calibration: Calibration, frame: ImageInput,
                       **stages: Unpack[StageChoices]) -> tuple[Calibration, CameraMotion]:
    """Re-anchor a calibration to the camera's present pose from a frame with obstacles on it.

    The frame is registered to the calibration with the free symbols it shows
    (:mod:`sbplan.detection.registration`), and the calibration is moved by that movement
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
    from ..detector import Detector  # here, not at the top: detector.py imports this package (a cycle)

    cells = Detector(calibration, **stages).find_cells(frame)
    motion = cells.camera
    updated = calibration.moved(motion.matrix)
    stats = dict(updated.stats)
    stats["updates"] = [*stats.get("updates", []), {**motion.to_json(), "symbols_found": cells.symbols_found}]
    log.info("calibration re-anchored, %s", motion.summary(), extra={"data": {"camera": motion.to_json()}})
    return replace(updated, stats=stats), motion


def calibrate(reference: ImageInput, *, symbol: ImageInput | None = None,
              workspace: Workspace | str | os.PathLike | None = None, cell_size: float | None = None,
              binarizer: str | Binarizer | None = None, extractor: str | ContourExtractor | None = None,
              approximator: str | ContourApproximator | None = None, matcher: str | DescriptorMatcher | None = None,
              mapper: str | OccupancyMapper | None = None,
              footprint: str | FootprintRefiner | None = None,
              progress: Callable[[str, float], None] | None = None) -> Calibration:
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
    binarizer, extractor, approximator, matcher, mapper, footprint : str or Stage, optional
        Stage names (or instances); defaults in :data:`DEFAULT_STAGES`.

    progress : callable(stage, fraction), optional
        Called between the steps with what comes next (``str``) and the share of the work done
        (``float``, 0 to 1). An exception it raises (e.g. :class:`~sbplan.errors.Cancelled`)
        stops the calibration there: the terminal app cancels this way.

    Raises
    ------
    CalibrationError
        No symbols, an irregular grid, or no shape that repeats.
    """
    step = progress if progress is not None else _no_progress
    step("reading the reference", 0.0)
    gray = as_gray(load_image(reference) if isinstance(reference, (str, os.PathLike)) else reference,
                   name="reference")
    # calibration's memory grows with the pixels (about 60 bytes each): refuse before, not during
    limits.check("image_pixels", gray.size, f"reference: {gray.shape[1]} x {gray.shape[0]} pixels",
                 "give a smaller image")
    if workspace is not None and not isinstance(workspace, Workspace):
        workspace = load_workspace(workspace)
    if cell_size is not None:
        if not 0 < cell_size <= MAX_METRES:
            raise InputError(f"cell_size: must be a positive number of metres up to {MAX_METRES:g}, got {cell_size}")
        base = workspace or Workspace()
        workspace = replace(base, pitch_m=(float(cell_size), float(cell_size)), origin_m=base.origin_m)
    workspace = workspace or Workspace()
    reg = registry.registry()
    chosen = {kind: reg.create(kind, given if given is not None else DEFAULT_STAGES[kind])
              for kind, given in (("binarizer", binarizer), ("extractor", extractor), ("approximator", approximator),
                                  ("matcher", matcher), ("mapper", mapper), ("footprint", footprint))}
    h, w = gray.shape
    points_range = (12, max(16, (h + w) // 2))
    matcher_stage = cast(DescriptorMatcher, chosen["matcher"])  # the registry made it for the kind "matcher"
    extractor_stage, approximator_stage = chosen["extractor"], chosen["approximator"]
    step("extracting contours", 0.02)
    # The first look, before the symbols' size is known, is at about the resolution the default
    # stages are made for (frames over FIRST_LOOK_PX wide halved, as often as it takes): at 4K
    # their local window is a quarter of a symbol, a tilted camera's symbols came out too unlike
    # to be found as a group, and the floor's grain was taken for the symbol.
    first = WorkScale(_first_look_factor(gray.shape), gray.shape)
    shapes = extract_shapes(gray, binarizer=chosen["binarizer"], points_range=points_range,
                            work=None if first.identity else first,
                            extractor=extractor_stage, approximator=approximator_stage, matcher=matcher_stage)
    given = None if symbol is None else _symbol_descriptor_from_image(
        symbol, extractor=chosen["extractor"], approximator=chosen["approximator"], matcher=chosen["matcher"])
    step("finding the symbol", 0.1)
    members = _completed(shapes, _symbol_members(shapes, chosen["matcher"], ref=given), chosen["matcher"])
    # Fit the binarizer to the symbol size found and run again: a window of a few symbol sizes
    # follows the light without swallowing the symbol itself.
    # Symbols far larger than the outline checks need are worked on in a reduced image
    # (sbplan.detection.working): a 4K camera costs what the symbols' size asks, not its pixels.
    size = float(np.sqrt(np.median(shapes.areas[members])))
    work = WorkScale(work_factor(size), gray.shape)
    work_arg = None if work.identity else work
    if not work.identity:
        points_range = (12, max(16, sum(work.work_shape) // 2))
    fit = getattr(chosen["binarizer"], "with_symbol_size", None)
    refit = fit(size * SYMBOL_WINDOW / work.factor) if fit is not None else chosen["binarizer"]
    # (a first look at a reduced resolution is no final outline either)
    if refit != chosen["binarizer"] or not work.identity or work.factor != first.factor:
        step("extracting contours at the symbol's size", 0.15)
        chosen["binarizer"] = refit
        shapes = extract_shapes(gray, binarizer=refit, points_range=points_range, work=work_arg,
                                extractor=extractor_stage, approximator=approximator_stage, matcher=matcher_stage)
        members = _completed(shapes, _symbol_members(shapes, chosen["matcher"], ref=given), chosen["matcher"])
    reference_descriptor = np.median(shapes.descriptors[members], axis=0)
    dist = distances_between(matcher_stage, shapes.descriptors, reference_descriptor[None, :])[:, 0]
    step("fitting the grid", 0.25)
    grid = fit_grid(shapes.centres[members])
    # What a symbol looks like in later images is not what it looks like in this one: measure the
    # symbols again in degraded copies of the reference (defocus, dimmer light, sensor noise).
    cells = grid.assign(shapes.centres[members])
    cell_area = np.empty((grid.rows, grid.cols))
    cell_area[cells[:, 0], cells[:, 1]] = shapes.areas[members]
    symbol_polygons = [shapes.polygons[i] for i in members[np.argsort(cells[:, 0] * grid.cols + cells[:, 1])]]
    step("measuring the symbols' outlines", 0.3)
    distance_map = signed_distance_map(symbol_polygons, gray.shape)
    degraded, deviations, degraded_polygons, degraded_cells, shifts = _degraded_symbols(
        gray, grid, reference_descriptor, cell_area, distance_map,
        binarizer=chosen["binarizer"], points_range=points_range, work=work_arg,
        extractor=extractor_stage, approximator=approximator_stage, matcher=matcher_stage, progress=step)
    # An obstacle that clips a symbol moves part of its outline by more than light and focus
    # move it; the tolerance sits outside what the degraded copies showed, and at least 1 px.
    outline_tolerance = float(max(1.25 * np.max(deviations), 1.0)) if len(deviations) else 3.0
    # ... and the other way round: how far defocus and light pull each reference point in
    step("measuring how light and focus move the outlines", 0.65)
    ref_points, _ = reference_samples(symbol_polygons)
    inner = inner_deviations(ref_points[degraded_cells], degraded_polygons, shifts)
    inner_tol = (inner_tolerance(inner, degraded_cells, grid.rows * grid.cols) if len(degraded_cells)
                 else np.full((grid.rows * grid.cols, ref_points.shape[1]), outline_tolerance))
    step("deriving the match threshold", 0.9)
    threshold, margin = match_threshold(chosen["matcher"], reference_descriptor,
                                        np.concatenate([dist[members], degraded]), np.delete(dist, members),
                                        area=float(np.median(shapes.areas[members])))
    order = np.argsort(cells[:, 0] * grid.cols + cells[:, 1])
    symbol_idx = members[order]
    others = np.setdiff1d(np.arange(len(shapes.polygons)), members)
    rng = np.random.default_rng(0)  # the sample of other contours is kept small and reproducible
    sample = rng.choice(others, size=min(len(others), 200), replace=False) if len(others) else others
    keep_degraded = rng.choice(len(degraded_polygons), size=min(len(degraded_polygons), 300), replace=False)
    n_points = shapes.points[symbol_idx]
    step("measuring edges and registration points", 0.93)
    stats = {
        "contours": shapes.n_contours,
        "after_length_filter": len(shapes.polygons),
        "symbols": int(len(members)),
        "symbol_distance_max": float(dist[members].max()),
        "other_distance_min": float(np.delete(dist, members).min()) if len(others) else None,
        "rejected_centres_px": np.round(shapes.centres[others][:500], 2).tolist(),
    }
    log.info("calibrated: grid %d x %d, threshold %.4f, margin %.1fx (%s)", grid.cols, grid.rows, threshold,
             margin, ", ".join(f"{k} {v.name}" for k, v in chosen.items()),
             extra={"data": {"grid": [grid.rows, grid.cols], "threshold": threshold, "margin": margin,
                             "stages": {k: v.name for k, v in chosen.items()}}})
    calibration = Calibration(
        image_shape=(h, w),
        stages={k: _stage_spec(v) for k, v in chosen.items()},
        grid=grid,
        symbol_polygons=[shapes.polygons[i] for i in symbol_idx],
        symbol_holes=[shapes.holes[i] for i in symbol_idx],
        other_polygons=[shapes.polygons[i] for i in sample],
        degraded_polygons=[degraded_polygons[i] for i in sorted(keep_degraded)],
        descriptor=reference_descriptor,
        threshold=threshold,
        margin=margin,
        symbol_area_px=float(np.median(shapes.areas[members])),
        symbol_points_range=(int(n_points.min() * 0.7), int(np.ceil(n_points.max() * 1.4))),
        outline_tolerance_px=outline_tolerance,
        inner_tolerance_px=inner_tol,
        edge_contrast=edge_contrast(gray, *edge_probes(symbol_polygons, EDGE_DEPTH_PX * work.factor)),
        registration_centres_px=_registration_centres(gray, symbol_polygons, grid, work),
        work_scale=work.factor,
        reference_thumbnail=thumbnail(gray),
        workspace=workspace,
        stats=stats,
    )
    step("done", 1.0)
    return calibration


def _no_progress(stage: str, fraction: float) -> None:
    pass


def _registration_centres(gray: np.ndarray, symbol_polygons: list[np.ndarray], grid: Grid,
                          work: WorkScale) -> np.ndarray:
    """Each cell's symbol's grey-level centre (rows, cols, 2), measured in the working image as
    detection measures frames': what registration pairs frames' symbols with
    (:func:`sbplan.detection.registration.grey_centres`); the grid's centre where a symbol's box
    leaves the image."""
    outlines = [work.to_work(p) for p in symbol_polygons]
    boxes = np.array([[p[:, 0].min(), p[:, 1].min(), p[:, 0].max(), p[:, 1].max()] for p in outlines])
    centres = work.to_frame(grey_centres(work.reduce(gray), boxes, centre_window(outlines)))
    fallback = grid.centres_px.reshape(-1, 2)
    bad = ~np.isfinite(centres).all(axis=1)
    centres[bad] = fallback[bad]
    return centres.reshape(grid.rows, grid.cols, 2)

def _degraded_symbols(gray: np.ndarray, grid: Grid, descriptor: np.ndarray, cell_area: np.ndarray,
                      distance_map: np.ndarray, *,
                      binarizer, extractor, approximator, matcher, points_range, work=None,
                      progress: Callable[[str, float], None] = _no_progress) -> tuple:
    """The reference's symbols in defocused, dimmed, dark-and-grainy and noisy copies of it.

    Returns their descriptor distances to ``descriptor``, their outlines' deviations from the
    reference outlines and common shifts (:func:`sbplan.detection.outline_checks.outline_deviation`), their
    polygons and their cells (flat, row-major), as ``(distances, deviations, polygons, cells,
    shifts)``.
    """
    rng = np.random.default_rng(0)  # reproducible noise
    g = gray.astype(np.float64)
    copies = [
        cv2.GaussianBlur(gray, (0, 0), 2.0),
        cv2.convertScaleAbs(gray, alpha=0.6),
        np.clip(0.3 * g + rng.normal(0, 4, g.shape), 0, 255).astype(np.uint8),
        np.clip(g + rng.normal(0, 8, g.shape), 0, 255).astype(np.uint8),
    ]
    distances: list[np.ndarray] = []
    deviations: list[np.ndarray] = []
    polygons: list[np.ndarray] = []
    cells_kept: list[np.ndarray] = []
    shifts: list[np.ndarray] = []
    for k, (what, image) in enumerate(zip(("defocused", "dimmed", "dark and grainy", "noisy"), copies)):
        progress(f"the symbols in a {what} copy", 0.35 + 0.075 * k)
        shapes = extract_shapes(image, binarizer=binarizer, extractor=extractor, approximator=approximator,
                                matcher=matcher, points_range=points_range, work=work)
        if not shapes.polygons:
            continue
        cells = grid.assign(shapes.centres)
        ok = cells[:, 0] >= 0
        ratio = np.full(len(cells), np.inf)
        ratio[ok] = shapes.areas[ok] / cell_area[cells[ok, 0], cells[ok, 1]]
        ok &= np.abs(np.log(ratio)) < np.log(1.3)
        if not ok.any():  # this degradation erased every symbol: it says nothing about them
            continue
        d = distances_between(matcher, shapes.descriptors[ok], descriptor[None, :])[:, 0]
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


#: Calibration's first look at a reference wider than this is at a halved resolution (or smaller).
FIRST_LOOK_PX = 2048


def _first_look_factor(shape: tuple[int, int]) -> int:
    """The power of two that brings a reference's width (and height, as wide) to FIRST_LOOK_PX or
    less."""
    factor, side = 1, max(int(shape[0]), int(shape[1]))
    while side / factor > FIRST_LOOK_PX:
        factor *= 2
    return factor


def _symbol_members(shapes: Shapes, matcher, *, ref: np.ndarray | None) -> np.ndarray:
    """Indices of the shapes that are the reference symbol: those near ``ref`` (the descriptor of a
    given symbol image) or, without one, the dominant repeated shape."""
    n = len(shapes.polygons)
    if n == 0:
        raise CalibrationError("no symbols found in the reference image (no dark shapes of symbol size)")
    if ref is not None:
        d = distances_between(matcher, shapes.descriptors, ref[None, :])[:, 0]
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


#: Two shapes are the same size when their areas differ by less than this factor.
SAME_SIZE = 1.35


def _same_size(areas: np.ndarray, area: np.ndarray | float) -> np.ndarray:
    """Whether ``areas`` and ``area`` (broadcast together) are within :data:`SAME_SIZE` of each
    other, either way."""
    return np.abs(np.log(areas / area)) < np.log(SAME_SIZE)


def _completed(shapes: Shapes, members: np.ndarray, matcher) -> np.ndarray:
    """``members`` and, at each position of their lattice that none of them holds, the shape of
    the symbol's size nearest to it, when one lies within half a symbol of it and is like the
    symbol by the matcher's own threshold.

    The grouping keeps shapes close to the group's median, and a lens bends the symbols at the
    frame's corners more than the rest: two of 50 such symbols (1024 x 768, barrel distortion)
    fell outside it and the grid was called irregular. The lattice says where a symbol must be;
    there a looser likeness is enough."""
    gaps = lattice_gaps(shapes.centres[members])
    if not len(gaps):
        return members
    median = np.median(shapes.descriptors[members], axis=0)
    dm = distances_between(matcher, shapes.descriptors, median[None, :])[:, 0]
    area = float(np.median(shapes.areas[members]))
    candidate = (dm < getattr(matcher, "default_threshold", 0.5)) & _same_size(shapes.areas, area)
    candidate[members] = False
    found = np.flatnonzero(candidate)
    if not len(found):
        return members
    reach = 0.5 * np.sqrt(area)
    gap_of = np.linalg.norm(shapes.centres[found][:, None, :] - gaps[None, :, :], axis=2)  # (candidates, gaps)
    added = {int(found[np.argmin(gap_of[:, g])]) for g in range(len(gaps)) if gap_of[:, g].min() <= reach}
    return np.union1d(members, np.fromiter(added, np.int64, len(added))) if added else members


def _dominant_repeated_shape(shapes: Shapes, matcher) -> np.ndarray:
    """The group of contours with the same shape and the same size that covers the most floor,
    among the groups of at least four (what a grid needs; the largest group when none has four).

    By area, not count: a textured floor repeats its grain's specks too, and seen by a 4K camera
    through a lens that bends the symbols' outlines apart, 35 specks of 140 px2 outnumbered every
    group of the symbols, 17000 px2 each (calibration failed on an "irregular grid")."""
    d = distances_between(matcher, shapes.descriptors, shapes.descriptors)
    same_size = _same_size(shapes.areas[:, None], shapes.areas[None, :])
    tight = 0.25 * getattr(matcher, "default_threshold", 0.5)
    alike = (d < tight) & same_size
    count = alike.sum(axis=1)
    cover = alike.astype(np.float64) @ np.asarray(shapes.areas, np.float64)
    seed = int(np.argmax(np.where(count >= 4, cover, -1.0))) if (count >= 4).any() else int(np.argmax(count))
    members = np.flatnonzero(alike[seed])
    # widen once around the group's median so the seed's own noise does not decide membership
    median = np.median(shapes.descriptors[members], axis=0)
    dm = distances_between(matcher, shapes.descriptors, median[None, :])[:, 0]
    spread = max(float(np.max(dm[members])), 1e-6)
    area = np.median(shapes.areas[members])
    return np.flatnonzero((dm <= 2.0 * spread) & _same_size(shapes.areas, area))
