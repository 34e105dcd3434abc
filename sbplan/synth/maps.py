"""The example maps under ``maps/``: named recipes and the builder that renders them exactly.

A map folder holds ``reference.png`` (the empty floor), ``scene-01.png`` (+ more), the ground truth
``scene-01.json`` (+ more) and ``workspace.toml`` (grid pitch in metres, origin, robot radius and a
default start and goal). Every file is a pure function of the recipe, so ``sbplan synth --map NAME``
rebuilds the committed folder byte for byte (PNG encoding by OpenCV is deterministic).

>>> from sbplan.synth.maps import MAPS
>>> "paper-8x6" in MAPS
True
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon, box

from ..errors import SceneError
from ..files import write_file_set
from ..imageio import encode_image
from .floor import FloorSpec, SceneSpec
from .render import render_reference, render_scene
from .truth import FREE, OCCUPIED, GroundTruth


@dataclass(frozen=True)
class MapRecipe:
    """Everything needed to rebuild one map folder.

    Attributes
    ----------
    name, description : str
    floor : FloorSpec
    scenes : tuple of (SceneSpec, int)
        Each scene and its seed; written as ``scene-01``, ``scene-02``, ...
    reference_seed : int
        Sensor-noise seed of ``reference.png``.
    reference_condition : str
        Condition whose camera geometry the reference shares (the camera is fixed).
    pitch_m : (float, float)
        Metres between neighbouring symbol centres along columns (x) and rows (y).
    radius_m : float
        Robot radius in metres.
    start_m, goal_m : (float, float) or None
        World ``(x, y)`` metres; None: chosen by :func:`choose_route` on the first scene's truth.
    """

    name: str
    description: str
    floor: FloorSpec
    scenes: tuple
    reference_seed: int = 0
    reference_condition: str = "clean"
    pitch_m: tuple = (0.5, 0.5)
    radius_m: float = 0.15
    start_m: tuple | None = None
    goal_m: tuple | None = None


#: Paper figure 6: centres of area of the symbols, by column and by row (pixels).
PAPER_COL_X = (47, 146, 247, 346, 445, 544, 644, 744)
PAPER_ROW_Y = (45, 138, 229, 322, 413, 506)


def _rotated_box(cx: float, cy: float, w: float, h: float, angle_deg: float) -> np.ndarray:
    a = math.radians(angle_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    pts = np.array([[-w, -h], [-w, h], [w, h], [w, -h]]) / 2.0
    return pts @ rot.T + (cx, cy)


def _disc(cx: float, cy: float, r: float, n: int = 72) -> np.ndarray:
    t = np.linspace(0, 2 * math.pi, n, endpoint=False)
    return np.c_[cx + r * np.cos(t), cy - r * np.sin(t)]


def _paper() -> MapRecipe:
    floor = FloorSpec(width=792, height=552, cols=8, rows=6, col_x=PAPER_COL_X, row_y=PAPER_ROW_Y, floor_seed=6)
    # Three obstacles placed by hand, each covering whole symbols with >= 14 px to spare and keeping
    # >= 10 px from every other symbol, so their occupied cells form three groups that do not touch
    # (not even diagonally): 6 + 4 + 3 = 13 hidden symbols, 35 visible.
    shelf = _rotated_box(203, 234.5, 170, 253, 3.0)            # cols 1-2, rows 1-3
    drum = _disc(600, 188, 100)                                  # cols 5-6, rows 1-2
    bench = np.array([(316, 484), (360, 474), (560, 476), (590, 492), (586, 544), (330, 546)], float)  # cols 3-5, row 5
    scene = SceneSpec(obstacles=[shelf, drum, bench], textures=("noise", "stripes", "labels"))
    return MapRecipe("paper-8x6", "the paper's worked example (figure 6): 8 columns × 6 rows of symbols, "
                     "3 obstacles hide 13", floor, ((scene, 1),), start_m=(0.25, 1.75), goal_m=(3.75, 1.75))


def _large() -> MapRecipe:
    floor = FloorSpec(width=1920, height=1080, cols=16, rows=12, floor_seed=16)
    scene = SceneSpec(n_obstacles=5, size=(1.0, 2.4), effects={"noise": 1.0})
    return MapRecipe("large-16x12", "a large floor: 16 columns × 12 rows of symbols at 1920 x 1080, five obstacles",
                     floor, ((scene, 3),), reference_condition="clean", pitch_m=(0.4, 0.4), radius_m=0.15)


def _adverse() -> MapRecipe:
    floor = FloorSpec(width=1024, height=768, cols=10, rows=7, floor_seed=21)
    scenes = (
        (SceneSpec(n_obstacles=4, condition="adverse"), 5),
        (SceneSpec(n_obstacles=4, condition="low-light"), 5),
    )
    return MapRecipe("adverse-lighting", "adverse lighting: gradient, shadows, glare, noise, JPEG; "
                     "scene-02 the same obstacles in low light", floor, scenes)


def _tilted() -> MapRecipe:
    floor = FloorSpec(width=1024, height=768, cols=10, rows=7, tilt=(4.0, -3.0), distortion=0.04, floor_seed=31)
    scene = SceneSpec(n_obstacles=3, kinds=("box", "cylinder"))
    return MapRecipe("tilted-camera", "a camera tilted 4 deg and -3 deg with mild barrel distortion "
                     "(reference shares the geometry)", floor, ((scene, 7),))


def _crowded() -> MapRecipe:
    floor = FloorSpec(width=1024, height=768, cols=12, rows=9, floor_seed=41)
    # a gap of about a pitch keeps the obstacles' cell groups apart, so that a route exists
    scene = SceneSpec(n_obstacles=10, size=(0.6, 1.3), min_gap=90.0, condition="textured")
    return MapRecipe("crowded", "a crowded floor: ten obstacles of every kind with strong textures on 12 columns × 9 rows",
                     floor, ((scene, 11),), radius_m=0.1)


def _edge_clips() -> MapRecipe:
    floor = FloorSpec(width=960, height=720, cols=8, rows=6, floor_seed=51)
    xs, ys = np.asarray(floor.col_x), np.asarray(floor.row_y)
    ext_lo, ext_hi = floor.symbol_rings_px()[0].min(axis=0), floor.symbol_rings_px()[0].max(axis=0)
    # Obstacles standing in the gaps between symbols, reaching a few pixels into the symbols beside
    # them: thin slivers (ambiguous cells) and small bites (occupied by a few per cent).
    gap_x = 0.5 * (xs[2] + ext_hi[0] + xs[3] + ext_lo[0])      # between columns 2 and 3
    half_w = 0.5 * ((xs[3] + ext_lo[0]) - (xs[2] + ext_hi[0])) + 2.5
    wall = _rotated_box(gap_x, 0.5 * (ys[1] + ys[4]), 2 * half_w, ys[4] - ys[1] + 20, 0.0)
    gap_y = 0.5 * (ys[4] + ext_hi[1] + ys[5] + ext_lo[1])      # between rows 4 and 5
    half_h = 0.5 * ((ys[5] + ext_lo[1]) - (ys[4] + ext_hi[1])) + 3.0
    beam = _rotated_box(0.5 * (xs[5] + xs[6]), gap_y, 2 * (xs[6] - xs[5]), 2 * half_h, 0.0)
    post = _disc(0.5 * (xs[5] + xs[6]), 0.5 * (ys[0] + ys[1]), 0.5 * min(np.diff(xs).min(), np.diff(ys).min()) - 4)
    scene = SceneSpec(obstacles=[wall, beam, post], textures=("noise", "gradient"))
    return MapRecipe("edge-clips", "obstacles in the gaps between symbols that only clip symbol edges "
                     "(slivers: ambiguous cells, small bites)", floor, ((scene, 13),), radius_m=0.1)


#: Map name -> recipe factory, in the order ``sbplan synth --list`` shows them.
RECIPES: dict[str, Callable[[], MapRecipe]] = {
    "paper-8x6": _paper, "large-16x12": _large, "adverse-lighting": _adverse, "tilted-camera": _tilted,
    "crowded": _crowded, "edge-clips": _edge_clips,
}
#: Map name -> one-line description.
MAPS: dict[str, str] = {
    "paper-8x6": "the paper's worked example (figure 6): 8 columns × 6 rows of symbols, 3 obstacles hide 13",
    "large-16x12": "a large floor: 16 columns × 12 rows of symbols at 1920 x 1080, five obstacles",
    "adverse-lighting": "adverse lighting (gradient, shadows, glare, noise, JPEG); scene-02 in low light",
    "tilted-camera": "a camera tilted a few degrees with mild lens distortion",
    "crowded": "a crowded floor: ten textured obstacles on 12 columns × 9 rows of symbols",
    "edge-clips": "obstacles between symbols that only clip symbol edges",
}


def recipe(name: str) -> MapRecipe:
    """The recipe of a named map (see :data:`MAPS`)."""
    if name not in RECIPES:
        raise SceneError(f"map: unknown map {name!r}; known: {', '.join(RECIPES)}")
    return RECIPES[name]()


# -- world coordinates ---------------------------------------------------------------------------
def floor_to_world(floor: FloorSpec, pts: np.ndarray, pitch_m, origin_m=None) -> np.ndarray:
    """World ``(x, y)`` metres of floor-plane pixels ``(N, 2)`` ``(x, y)``.

    The grid is the ruler: pixels are mapped to fractional lattice ``(col, row)`` piecewise
    linearly between symbol centres (extrapolated beyond them), then to metres with y up.
    """
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    col = _lattice(np.asarray(floor.col_x), pts[:, 0])
    row = _lattice(np.asarray(floor.row_y), pts[:, 1])
    ox, oy = origin_m if origin_m is not None else (pitch_m[0] / 2, pitch_m[1] / 2)
    return np.column_stack([ox + col * pitch_m[0], oy + (floor.rows - 1 - row) * pitch_m[1]])


def _lattice(centres: np.ndarray, v: np.ndarray) -> np.ndarray:
    n = len(centres)
    if n == 1:
        return np.zeros_like(v)
    idx = np.interp(v, centres, np.arange(n, dtype=float))
    lo, hi = v < centres[0], v > centres[-1]
    idx[lo] = (v[lo] - centres[0]) / (centres[1] - centres[0])
    idx[hi] = n - 1 + (v[hi] - centres[-1]) / (centres[-1] - centres[-2])
    return idx


def route_clearance(floor: FloorSpec, truth: GroundTruth, point_m, pitch_m) -> float:
    """Distance in metres from a world point to the nearest true obstacle (floor plane)."""
    polys = [Polygon(floor_to_world(floor, p, pitch_m)) for p in truth.obstacles_floor]
    if not polys:
        return math.inf
    return float(shapely.union_all(polys).distance(Point(point_m)))


def route_blocked(floor: FloorSpec, truth: GroundTruth, start_m, goal_m, pitch_m) -> bool:
    """True when the straight segment start-goal crosses a true obstacle."""
    polys = [Polygon(floor_to_world(floor, p, pitch_m)) for p in truth.obstacles_floor]
    return bool(polys) and shapely.union_all(polys).intersects(LineString([start_m, goal_m]))


def choose_route(floor: FloorSpec, truth: GroundTruth, pitch_m, radius_m) -> tuple[tuple, tuple]:
    """A default start and goal for a map: on opposite sides, straight line blocked.

    Candidates are the centres of free cells at least ``radius_m + 0.1`` m from every true
    obstacle and ``radius_m + 0.05`` m from the minimum-area rectangle of every 8-connected group
    of occupied cells (one pitch-wide square per cell: what a detector reports and the planner
    avoids stays clear of them too). Start in the left third of
    the columns, goal in the right third; the first blocked pair in a fixed order (rows nearest
    the middle first, then outer columns first) wins.

    Raises
    ------
    SceneError
        No such pair exists.
    """
    rows, cols = truth.cells.shape
    px, py = pitch_m
    ox, oy = px / 2, py / 2

    def world(c, r):
        return (round(ox + c * px, 6), round(oy + (rows - 1 - r) * py, 6))

    # Each 8-connected group of occupied cells becomes one obstacle whose minimum-area rectangle
    # the planner avoids: keep start and goal out of those rectangles.
    n, labels = cv2.connectedComponents((truth.cells == OCCUPIED).astype(np.uint8), connectivity=8)
    rects = []
    for k in range(1, n):
        squares = [box(x - px / 2, y - py / 2, x + px / 2, y + py / 2)
                   for r, c in zip(*np.nonzero(labels == k)) for x, y in [world(c, r)]]
        rects.append(shapely.union_all(squares).minimum_rotated_rectangle)
    occupied = shapely.union_all(rects) if rects else None

    def fits(c, r):
        if truth.cells[r, c] != FREE:
            return False
        p = world(c, r)
        # the planner's bounds are the grid's outer cell edges
        if min(p[0], cols * px - p[0], p[1], rows * py - p[1]) < radius_m + 0.02:
            return False
        if occupied is not None and occupied.distance(Point(p)) < radius_m + 0.05:
            return False
        return route_clearance(floor, truth, p, pitch_m) >= radius_m + 0.1

    order = sorted(range(rows), key=lambda r: (abs(r - (rows - 1) / 2), r))
    q = max(1, cols // 3)
    starts = [world(c, r) for r in order for c in range(q) if fits(c, r)]
    goals = [world(c, r) for r in order for c in range(cols - 1, cols - 1 - q, -1) if fits(c, r)]
    for s in starts:
        for g in goals:
            if route_blocked(floor, truth, s, g, pitch_m):
                return s, g
    raise SceneError("map: no start and goal with a blocked straight line and enough clearance")


# -- building --------------------------------------------------------------------------------------
def render_map(rec: MapRecipe) -> dict[str, np.ndarray | GroundTruth | str]:
    """Render a map in memory: ``{"reference.png": img, "scene-01.png": img, "scene-01.json": truth,
    ..., "workspace.toml": text}``."""
    out: dict = {"reference.png": render_reference(rec.floor, seed=rec.reference_seed,
                                                   condition=rec.reference_condition)}
    truths = []
    for i, (scene, seed) in enumerate(rec.scenes, start=1):
        img, truth = render_scene(rec.floor, scene, seed=seed)
        out[f"scene-{i:02d}.png"] = img
        out[f"scene-{i:02d}.json"] = truth
        truths.append(truth)
    start, goal = rec.start_m, rec.goal_m
    if start is None or goal is None:
        start, goal = choose_route(rec.floor, truths[0], rec.pitch_m, rec.radius_m)
    out["workspace.toml"] = workspace_toml(rec, start, goal)
    return out


def workspace_toml(rec: MapRecipe, start_m, goal_m) -> str:
    """The ``workspace.toml`` text of a map (origin: the bottom-left symbol at half a pitch)."""
    px, py = rec.pitch_m
    return (f"# {rec.name}: {rec.description}\n"
            f"# Rebuild with: sbplan synth --map {rec.name}\n"
            "[grid]\n"
            f"pitch_m = [{px}, {py}]\n"
            "[origin]\n"
            f"xy_m = [{px / 2}, {py / 2}]\n"
            "[robot]\n"
            f"radius_m = {rec.radius_m}\n"
            "[route]\n"
            f"start_m = [{start_m[0]}, {start_m[1]}]\n"
            f"goal_m = [{goal_m[0]}, {goal_m[1]}]\n")


def build_map(name: str, out: str | os.PathLike | None = None) -> Path:
    """Render a named map and write its folder atomically (default ``maps/NAME``).

    Returns
    -------
    Path
        The folder written.
    """
    rec = recipe(name)
    folder = Path(out) if out is not None else Path("maps") / name
    files: dict[str, bytes | str] = {}
    for fname, item in render_map(rec).items():
        if isinstance(item, np.ndarray):
            files[fname] = encode_image(fname, item)
        elif isinstance(item, GroundTruth):
            files[fname] = item.to_json()
        else:
            files[fname] = item
    # one unit: a scene beside another run's truth would score detection against the wrong answer
    return write_file_set(folder, files)
