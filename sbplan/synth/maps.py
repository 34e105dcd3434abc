"""The example maps under ``maps/``: definitions, and the generator that rebuilds them exactly.

A map folder holds ``reference.png`` (the empty floor), ``scene-XX.png`` with ground truth
``scene-XX.json``, and ``workspace.toml`` (grid pitch in metres, origin, robot radius, default
start and goal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from shapely.geometry import LineString, Point, Polygon
from shapely.ops import unary_union

from ..errors import SceneError
from .floor import FloorSpec, SceneSpec
from .render import render_reference, render_scene
from .truth import GroundTruth


@dataclass(frozen=True)
class MapDef:
    """One example map: the floor, its scenes (spec, seed) and the workspace calibration."""

    name: str
    description: str
    floor: FloorSpec
    scenes: tuple
    pitch_m: tuple = (0.5, 0.5)
    origin_m: tuple = (0.25, 0.25)
    robot_radius_m: float = 0.15
    reference_condition: str = "clean"
    reference_seed: int = 0
    extra: dict = field(default_factory=dict)


def _box(x0, y0, x1, y1, skew=0.0):
    return [(x0 + skew, y0), (x0, y1), (x1 - skew, y1), (x1, y0)]


def _paper_floor() -> FloorSpec:
    return FloorSpec(width=792, height=552, cols=8, rows=6,
                     col_x=(47, 146, 247, 346, 445, 544, 644, 744), row_y=(45, 138, 229, 322, 413, 506),
                     symbol_size=46, floor_seed=2009)


# The paper's example: three obstacles hiding 4 + 3 + 6 = 13 symbols, each with >= 25 px of clear
# floor to every symbol it does not hide (so 0 ambiguous cells).
_PAPER_OBSTACLES = (
    _box(108, 101, 285, 268, skew=6),                                         # cols 1-2, rows 1-2
    [(420, 8), (472, 8), (486, 30), (486, 250), (470, 268), (421, 268), (405, 250), (405, 30)],  # col 4, rows 0-2
    _box(506, 376, 783, 546),                                                 # cols 5-7, rows 4-5
)

_EDGE_FLOOR = FloorSpec(width=800, height=600, cols=8, rows=6, floor_seed=5)


def _edge_obstacles() -> tuple:
    """Obstacles in the gaps between symbols that only clip their edges (slivers and small bites)."""
    xs, ys = _EDGE_FLOOR.col_x, _EDGE_FLOOR.row_y
    rings = np.vstack(_EDGE_FLOOR.symbol_rings_px())
    (lx, ty), (rx, by) = rings.min(axis=0), rings.max(axis=0)  # symbol bounds about its centre
    return (
        # a plank in the gap between columns 1 and 2: touches column 1's flag tips by 1.5 px
        # (slivers) and cuts 3 px into column 2's poles (small bites, just occupied)
        _box(xs[1] + rx - 1.5, ys[0] - 30, xs[2] + lx + 3.0, ys[2] + 30),
        # a crate in the gap between rows 3-4 and columns 3-4, its corners biting into the symbols
        _box(xs[3] + rx - 6, ys[3] + by - 6, xs[4] + lx + 6, ys[4] + ty + 6),
        # a box hiding two symbols fully
        _box(xs[5] + lx - 8, ys[1] + ty - 8, xs[6] + rx + 8, ys[1] + by + 8),
    )


MAPS: dict[str, MapDef] = {
    "paper-8x6": MapDef(
        "paper-8x6", "the paper's worked example: 8 x 6 symbols at figure 6's centres, 3 obstacles hide 13",
        _paper_floor(),
        ((SceneSpec(obstacles=_PAPER_OBSTACLES, condition="clean"), 1),
         (SceneSpec(obstacles=_PAPER_OBSTACLES, condition="shadows"), 2))),
    "large-16x12": MapDef(
        "large-16x12", "a large floor: 16 x 12 symbols on a 1920 x 1080 image, 8 random obstacles",
        FloorSpec(width=1920, height=1080, cols=16, rows=12, floor_seed=16),
        ((SceneSpec(n_obstacles=8, condition="clean"), 12),)),
    "adverse-lighting": MapDef(
        "adverse-lighting", "10 x 8 floor seen under gradient + shadows + glare, highlights, and low light",
        FloorSpec(width=1024, height=768, cols=10, rows=8, floor_seed=7),
        ((SceneSpec(n_obstacles=4, condition="adverse"), 4),
         (SceneSpec(n_obstacles=4, condition="highlights"), 4),
         (SceneSpec(n_obstacles=4, condition="low-light"), 4))),
    "tilted-camera": MapDef(
        "tilted-camera", "camera tilted 4 x 2.5 degrees with barrel distortion 0.04 (reference shares it)",
        FloorSpec(width=1024, height=768, cols=10, rows=8, tilt=(4.0, 2.5), distortion=0.04, floor_seed=8),
        ((SceneSpec(n_obstacles=4, condition="clean"), 21),)),
    "crowded": MapDef(
        "crowded", "12 x 9 floor crowded with 12 strongly textured obstacles",
        FloorSpec(width=1200, height=900, cols=12, rows=9, floor_seed=9),
        ((SceneSpec(n_obstacles=12, size=(0.7, 1.8), condition="textured", min_gap=4.0), 31),)),
    "edge-clip": MapDef(
        "edge-clip", "obstacles that only clip symbol edges: slivers (ambiguous) and small bites",
        _EDGE_FLOOR, ((SceneSpec(obstacles=_edge_obstacles(), condition="clean"), 41),)),
}


# -- workspace geometry ------------------------------------------------------------------------
def floor_to_world(floor: FloorSpec, pts: np.ndarray, pitch_m, origin_m) -> np.ndarray:
    """World ``(x, y)`` metres of floor-plane pixels (x along columns, y up toward row 0)."""
    pts = np.asarray(pts, dtype=float)
    dx, dy = floor.pitch_px
    col = (pts[..., 0] - floor.col_x[0]) / dx
    row = (pts[..., 1] - floor.row_y[0]) / dy
    return np.stack([origin_m[0] + col * pitch_m[0], origin_m[1] + (floor.rows - 1 - row) * pitch_m[1]], axis=-1)


def choose_route(floor: FloorSpec, truth: GroundTruth, pitch_m, origin_m, radius: float) -> tuple[list, list]:
    """A default start and goal (metres): both >= radius + 0.1 m from every obstacle and from the
    image's edge, and the straight line between them blocked by an obstacle."""
    obstacles = [Polygon(floor_to_world(floor, p, pitch_m, origin_m)) for p in truth.obstacles_floor]
    if not obstacles:
        raise SceneError("obstacles: a map needs obstacles to choose a bending route")
    union = unary_union(obstacles)
    corners = floor_to_world(floor, np.array([[0, 0], [floor.width - 1, floor.height - 1]]), pitch_m, origin_m)
    (x0, y1), (x1, y0) = corners
    clear = radius + 0.1
    xs = np.arange(x0 + clear, x1 - clear, 0.05)
    ys = np.arange(y0 + clear, y1 - clear, 0.05)
    pts = [(float(x), float(y)) for x in xs for y in ys if union.distance(Point(x, y)) >= clear]
    if not pts:
        raise SceneError("obstacles: no free point for a start or goal")
    pts_a = np.array(pts)
    mid_y = 0.5 * (y0 + y1)
    width = x1 - x0
    starts = sorted(pts, key=lambda p: math.hypot(p[0] - (x0 + 0.1 * width), p[1] - mid_y))[:200]
    goals = sorted(pts, key=lambda p: math.hypot(p[0] - (x1 - 0.1 * width), p[1] - mid_y))[:200]
    del pts_a
    for s in starts[:60]:
        for g in goals[:60]:
            if LineString([s, g]).intersects(union):
                return [round(s[0], 2), round(s[1], 2)], [round(g[0], 2), round(g[1], 2)]
    # no blocked left-right pair: try any pair across the floor
    for s in starts:
        for g in sorted(pts, key=lambda p: -math.hypot(p[0] - s[0], p[1] - s[1]))[:300]:
            if LineString([s, g]).intersects(union):
                return [round(s[0], 2), round(s[1], 2)], [round(g[0], 2), round(g[1], 2)]
    raise SceneError("obstacles: no start/goal pair whose straight line is blocked")


def workspace_toml(pitch_m, origin_m, radius: float, start, goal) -> str:
    f = lambda v: f"{float(v):.6g}"  # noqa: E731
    return (
        "# Workspace calibration of this map (written by `sbplan synth --map`).\n"
        "[grid]\n"
        f"pitch_m = [{f(pitch_m[0])}, {f(pitch_m[1])}]      # metres between neighbouring symbol centres along columns (x) and rows (y)\n"
        "[origin]\n"
        f"xy_m = [{f(origin_m[0])}, {f(origin_m[1])}]       # world (x, y) of the centre of the bottom-left symbol (row = rows-1, col = 0)\n"
        "[robot]\n"
        f"radius_m = {f(radius)}\n"
        "[route]\n"
        f"start_m = [{f(start[0])}, {f(start[1])}]\n"
        f"goal_m = [{f(goal[0])}, {f(goal[1])}]\n"
    )


# -- building ----------------------------------------------------------------------------------
def map_names() -> list[str]:
    return list(MAPS)


def build_map(name: str) -> dict[str, Any]:
    """Render a map in memory: ``{"reference", "scenes": [(image, truth)], "workspace": str}``."""
    if name not in MAPS:
        raise SceneError(f"map: unknown map {name!r}; maps: {', '.join(MAPS)}")
    m = MAPS[name]
    ref = render_reference(m.floor, seed=m.reference_seed, condition=m.reference_condition)
    scenes = []
    for spec, seed in m.scenes:
        img, truth = render_scene(m.floor, spec, seed=seed)
        truth.params["map"] = name
        scenes.append((img, truth))
    start, goal = choose_route(m.floor, scenes[0][1], m.pitch_m, m.origin_m, m.robot_radius_m)
    return {"reference": ref, "scenes": scenes,
            "workspace": workspace_toml(m.pitch_m, m.origin_m, m.robot_radius_m, start, goal),
            "start_m": start, "goal_m": goal}


def write_map(name: str, out_dir: str | Path | None = None) -> Path:
    """Rebuild map ``name`` into ``out_dir`` (default ``maps/NAME``); every file written atomically."""
    from ..imageio import write_atomic, write_image

    built = build_map(name)
    out = Path(out_dir) if out_dir is not None else Path("maps") / name
    write_image(out / "reference.png", built["reference"])
    for i, (img, truth) in enumerate(built["scenes"], start=1):
        write_image(out / f"scene-{i:02d}.png", img)
        write_atomic(out / f"scene-{i:02d}.json", truth.to_json())
    write_atomic(out / "workspace.toml", built["workspace"])
    return out
