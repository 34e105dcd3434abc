"""Accuracy of detection against the renderer's ground truth: cells and footprints.

Cells: ground truth names each cell occupied, free or ambiguous (a sliver of overlap); ambiguous
cells are left out of the score. A cell is a true positive when it is occupied in both.

Footprints (:func:`score_footprints`): the true obstacles' pixels against the reported outlines,
in the calibration's pixels and within the floor the grid covers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np

from ..errors import InputError
from ..synth import FloorSpec, GroundTruth, SceneSpec, render_reference, render_scene


@dataclass(frozen=True)
class Scores:
    tp: int = 0
    fp: int = 0
    fn: int = 0
    tn: int = 0

    def __add__(self, other: "Scores") -> "Scores":
        return Scores(self.tp + other.tp, self.fp + other.fp, self.fn + other.fn, self.tn + other.tn)

    @property
    def precision(self) -> float:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else 1.0

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else 1.0

    @property
    def f1(self) -> float:
        denominator = 2 * self.tp + self.fp + self.fn
        return 2 * self.tp / denominator if denominator else 1.0


def score_cells(predicted: np.ndarray, truth: np.ndarray) -> Scores:
    """Compare predicted occupancy with ground truth.

    Parameters
    ----------
    predicted : ndarray of shape (rows, cols), bool
        True where a cell is called occupied.
    truth : ndarray of shape (rows, cols), int
        1 occupied, 0 free, -1 ambiguous (excluded).
    """
    predicted, truth = np.asarray(predicted, bool), np.asarray(truth)
    if predicted.shape != truth.shape:
        raise InputError(f"predicted: shape {predicted.shape} differs from the ground truth's {truth.shape}")
    known = truth >= 0
    occ = truth == 1
    return Scores(
        tp=int((predicted & occ & known).sum()),
        fp=int((predicted & ~occ & known).sum()),
        fn=int((~predicted & occ & known).sum()),
        tn=int((~predicted & ~occ & known).sum()),
    )


def condition_scenes(condition: str, *, scenes: int = 5, size: tuple[int, int] = (1280, 960),
                     grid: tuple[int, int] = (10, 5), seed: int = 0, layout: str | None = None,
                     **floor_options: Any) -> Iterator[tuple[np.ndarray, np.ndarray, GroundTruth]]:
    """Yield ``(reference, scene, truth)`` for one condition of the renderer's suite, seeded.

    The reference shares the scenes' camera (tilt, distortion) and is lit with base lighting.
    """
    width, height = size
    cols, rows = grid
    extra = dict(floor_options)
    if layout is not None:
        extra["layout"] = layout
    floor = FloorSpec(width=width, height=height, cols=cols, rows=rows, **extra)
    reference = render_reference(floor, seed=seed, condition=condition)
    for k in range(scenes):
        image, truth = render_scene(floor, SceneSpec(condition=condition), seed=seed * 1000 + k + 1)
        yield reference, image, truth


@dataclass(frozen=True)
class FootprintScores:
    """Footprints of some frames against the true obstacles, summed (``+`` adds frames).

    Attributes
    ----------
    true_px, found_px : int
        Pixels of the obstacles the cells can see (those hiding more than the occupied fraction
        of a truly occupied cell's symbol), and how many of them the reported outlines hold.
    reported_px : int
        Pixels the reported outlines hold, but for those of obstacles the cells cannot see (a
        footprint that reaches one holds obstacle, not free floor).
    all_true_px, all_found_px : int
        The same for every obstacle (the cells cannot see one standing between symbols).
    unseen : int
        Obstacles the cells cannot see (in the floor's area).
    model_px : dict
        Obstacle model -> pixels its polygons hold (the planner's obstacles drawn in pixels; the
        same pixels left out).
    outline_m2, parts_m2 : float
        The outlines' area and the ``parts`` model's rectangles' (summed) area, square metres.
    free_points : int
        Points of the floor (a half-pitch lattice) at least ``clearance`` from every true obstacle:
        where a start or goal may be put.
    swallowed : dict
        Obstacle model -> how many of those points its polygons hold (planning from there fails).
    """

    true_px: int = 0
    found_px: int = 0
    reported_px: int = 0
    all_true_px: int = 0
    all_found_px: int = 0
    unseen: int = 0
    model_px: dict = field(default_factory=dict)
    outline_m2: float = 0.0
    parts_m2: float = 0.0
    free_points: int = 0
    swallowed: dict = field(default_factory=dict)

    def __add__(self, other: "FootprintScores") -> "FootprintScores":
        keys = set(self.swallowed) | set(other.swallowed)
        mkeys = set(self.model_px) | set(other.model_px)
        return FootprintScores(
            self.true_px + other.true_px, self.found_px + other.found_px, self.reported_px + other.reported_px,
            self.all_true_px + other.all_true_px, self.all_found_px + other.all_found_px,
            self.unseen + other.unseen, {k: self.model_px.get(k, 0) + other.model_px.get(k, 0) for k in mkeys},
            self.outline_m2 + other.outline_m2, self.parts_m2 + other.parts_m2,
            self.free_points + other.free_points,
            {k: self.swallowed.get(k, 0) + other.swallowed.get(k, 0) for k in keys})

    @property
    def recall(self) -> float:
        """Share of the seen obstacles' pixels inside the reported outlines."""
        return self.found_px / self.true_px if self.true_px else 1.0

    @property
    def all_recall(self) -> float:
        return self.all_found_px / self.all_true_px if self.all_true_px else 1.0

    @property
    def area_ratio(self) -> float:
        """Reported pixels over the seen obstacles' pixels."""
        return self.reported_px / self.true_px if self.true_px else float("nan")

    def model_ratio(self, model: str) -> float:
        return self.model_px.get(model, 0) / self.true_px if self.true_px else float("nan")

    @property
    def parts_ratio(self) -> float:
        """The ``parts`` rectangles' area over the outlines' (both in metres)."""
        return self.parts_m2 / self.outline_m2 if self.outline_m2 else float("nan")


def _fill(shape: tuple[int, int], polygons) -> np.ndarray:
    import cv2

    m = np.zeros(shape, np.uint8)
    polys = [np.rint(np.asarray(p, dtype=np.float64) * 16).astype(np.int32) for p in polygons if len(p) >= 3]
    if polys:
        cv2.fillPoly(m, polys, 1, cv2.LINE_8, shift=4)
    return m.astype(bool)


def score_footprints(detection: Any, truth: Any, *, clearance: float = 0.25) -> FootprintScores:
    """Score one detection's footprints and obstacle models against the scene's ground truth.

    Everything is compared in the calibration's pixels (the true outlines are moved there when the
    camera moved) and within the floor the grid covers (what the planner plans on). An obstacle is
    *seen* when it covers part of the symbol of a cell the ground truth calls occupied: the
    footprint's recall is over those; one standing between symbols is no footprint's to find.

    Parameters
    ----------
    detection : sbplan.Detection
    truth : sbplan.synth.GroundTruth
    clearance : float
        In grid pitches: how far from every true obstacle a floor point must be to count as a
        free place for a start or a goal.
    """
    from ..detection.obstacles import OBSTACLE_MODELS
    from shapely import contains_xy
    from shapely.geometry import Polygon
    import cv2

    cal = detection.calibration
    shape = tuple(cal.image_shape)
    grid = cal.grid
    corners = grid.cell_corners_px()
    ring = np.concatenate([corners[0, :], corners[1:, -1], corners[-1, -2::-1], corners[-2:0:-1, 0]])
    floor = _fill(shape, [ring])
    masks = [m & floor for m in truth.obstacle_masks(shape)]
    occupied = np.flatnonzero(np.asarray(truth.cells).ravel() == 1)
    symbols = [_fill(shape, [cal.symbol_polygons[c]]) for c in occupied]
    seen = [m.any() and any((m & s).any() for s in symbols) for m in masks]
    union = np.zeros(shape, bool)
    seen_union = np.zeros(shape, bool)
    for m, v in zip(masks, seen):
        union |= m
        if v:
            seen_union |= m
    # what a footprint holds of an obstacle the cells cannot see is obstacle, not floor: it is not
    # counted against the area (nor for the recall, which is over the seen obstacles)
    counted = floor & ~(union & ~seen_union)
    reported = _fill(shape, [ob.outline_px for ob in detection.obstacles]) & floor
    model_px = {model: int((_fill(shape, [p for ob in detection.obstacles for p in ob.polygons_px(model)]) & counted).sum())
                for model in OBSTACLE_MODELS}
    outline_m2 = parts_m2 = 0.0
    if all(ob.outline_m is not None for ob in detection.obstacles):
        outline_m2 = sum(Polygon(ob.outline_m).area for ob in detection.obstacles)
        parts_m2 = sum(Polygon(p).area for ob in detection.obstacles for p in ob.parts_m)
    # free places: a half-pitch lattice over the floor, away from every true obstacle
    step = 0.5
    cols = np.arange(-0.5 + step / 2, grid.cols - 0.5, step)
    rows = np.arange(-0.5 + step / 2, grid.rows - 0.5, step)
    lattice = np.stack(np.meshgrid(cols, rows), axis=-1).reshape(-1, 2)
    pts = grid.lattice_to_px(lattice)
    dist = cv2.distanceTransform((~union).astype(np.uint8), cv2.DIST_L2, 5)
    ij = np.clip(np.rint(pts).astype(np.int64), 0, [shape[1] - 1, shape[0] - 1])
    free = dist[ij[:, 1], ij[:, 0]] >= clearance * float(min(grid.pitch_px))
    swallowed = {}
    world = cal.pixels_to_world(pts[free])
    for model in OBSTACLE_MODELS:
        inside = np.zeros(len(world), bool)
        for p in detection.planner_obstacles(model) if len(world) else []:
            inside |= contains_xy(Polygon(p), world[:, 0], world[:, 1])
        swallowed[model] = int(inside.sum())
    return FootprintScores(
        true_px=int(seen_union.sum()), found_px=int((seen_union & reported).sum()), reported_px=int((reported & counted).sum()),
        all_true_px=int(union.sum()), all_found_px=int((union & reported).sum()),
        unseen=sum(1 for m, v in zip(masks, seen) if m.any() and not v), model_px=model_px,
        outline_m2=outline_m2, parts_m2=parts_m2, free_points=int(free.sum()), swallowed=swallowed)
