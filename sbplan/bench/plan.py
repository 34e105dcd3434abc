"""``sbplan bench plan``: route length against the exact optimum and query time of every planner.

Worlds (all seeded): random worlds of 5, 20, 50 and 200 rotated rectangles in a 100 x 100 square
(side ~ 40 / sqrt(n), so about 16 % of the floor is covered at every n); the two 450 x 450 OMPL maze
images of ``maps/ompl-mazes`` (pixel units, split into rectangles by the occupancy loader); and the
true obstacles of every ``maps/*/scene-01.json`` (floor pixels -> metres through the grid, the map's
``workspace.toml`` radius, start and goal).

What is timed (``time.perf_counter``, one thread, medians over the queries):
- ``build``: ``PlanningMap(...)`` from the obstacles: enlargement, corners, spatial index.
- ``cold``: one query on a map just built (obstacles loaded, visibility cache empty): endpoint
  checks + the search. This is the figure the speed targets refer to.
- ``warm``: the same queries in sequence on one map, the visibility cache kept between them.
- ``replan``: ``sbplan.replan`` after one new obstacle (a square put on the route's middle leg):
  map copy + incremental cache update + the new search.
- OMPL planners: ``solve_ompl`` (the ``sbplan.plan`` path for them) with the time limit, the
  found path simplified; length relative to the exact optimum of the same query.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import os
import platform
import statistics
import sys
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np
import shapely
from ompl import tools as ot
from shapely import affinity
from shapely.geometry import LineString, Polygon, box

from .. import replan
from ..errors import InputError, PlanningError
from ..planning import PlanningMap, load_obstacles
from ..planning.ompl_planners import OMPL_PLANNERS, allocate, make_setup, quiet, set_query, solve_ompl
from ..synth.floor import FloorSpec
from ..synth.maps import floor_to_world
from ..workspace import load_workspace

HELP = "route planners: path length vs the exact optimum and query times on random worlds, mazes, maps"
DESCRIPTION = HELP + ". See the module docstring (or docs/planning.md) for what is timed."

ALL_OMPL = ("rrt-connect", "rrt-star", "informed-rrt-star", "prm-star", "bit-star", "fmt-star")
RECT_COUNTS = (5, 20, 50, 200)
SIZE = 100.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true",
                        help="short run: fewer queries, OMPL planners with 0.2 s on 2 queries, no maps/")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--queries", type=int, default=None, help="aux-corner queries per world (default 40, quick 10)")
    parser.add_argument("--ompl-queries", type=int, default=None,
                        help="queries per world for the OMPL planners (default 3, quick 1)")
    parser.add_argument("--time-limit", type=float, default=None, help="seconds per OMPL solve (default 1, quick 0.2)")
    parser.add_argument("--planners", default=",".join(ALL_OMPL), help="OMPL planners to compare (comma-separated)")
    parser.add_argument("--worlds", default="", help="only these worlds (comma-separated names, default all)")
    parser.add_argument("--maps-dir", default="maps", metavar="DIR", help="folder of the maps (default maps)")
    parser.add_argument("--ompl-log", metavar="FILE",
                        help="also run ompl.tools.Benchmark (aux-corner + the OMPL planners, first query "
                             "of each world) and write its log(s): FILE for one world, FILE-<world>.log for several")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")


# -- worlds --------------------------------------------------------------------------------------
def rect_world(n: int, seed: int) -> list:
    """n rotated rectangles in [0, SIZE]^2 (shapely polygons), side ~ U(0.5, 1.5) * 40 / sqrt(n)."""
    rng = np.random.default_rng([seed, n])
    s = 40.0 / math.sqrt(n)
    out = []
    for _ in range(n):
        cx, cy = rng.uniform(0, SIZE, 2)
        w, h = rng.uniform(0.5, 1.5, 2) * s
        out.append(affinity.rotate(box(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2), rng.uniform(0, 180)))
    return out


def _free_queries(pm, rng, k: int, *, min_dist: float) -> list:
    """k (start, goal) pairs of free points at least min_dist apart, connected (solvable)."""
    x0, y0, x1, y1 = pm.bounds
    out: list[tuple[np.ndarray, np.ndarray]] = []
    for _ in range(200 * k):
        if len(out) == k:
            break
        p = rng.uniform((x0, y0), (x1, y1), (2, 2))
        if np.hypot(*(p[1] - p[0])) < min_dist or pm.vmap.covered(p).any():
            continue
        try:
            pm.solve(p[0], p[1], time_limit=10)
        except PlanningError:
            continue
        out.append((p[0], p[1]))
    return out


def worlds(args, seed: int, quick: bool):
    """Yield (name, obstacles, bounds, radius, queries) per world."""
    nq = args.queries or (10 if quick else 40)
    wanted = {w for w in args.worlds.split(",") if w}
    for n in RECT_COUNTS:
        name = f"rect-{n}"
        if wanted and name not in wanted:
            continue
        obs = rect_world(n, seed)
        bounds = (0.0, 0.0, SIZE, SIZE)
        pm = PlanningMap(obs, robot_radius=0.5, bounds=bounds)
        yield name, obs, bounds, 0.5, _free_queries(pm, np.random.default_rng([seed, n, 1]), nq, min_dist=30)
    maps = Path(args.maps_dir)
    for maze in sorted((maps / "ompl-mazes").glob("ompl-maze-*.png")):
        name = maze.stem.replace("ompl-", "")
        if wanted and name not in wanted:
            continue
        os_ = load_obstacles(maze)
        pm = PlanningMap(os_.polygons, robot_radius=2.0, bounds=os_.bounds)
        # The maze's own entrance (top) to its exit (bottom right), then random pairs.
        q = [(np.array([205.0, 445.0]), np.array([445.0, 55.0]))]
        q += _free_queries(pm, np.random.default_rng([seed, 7]), nq - 1, min_dist=150)
        yield name, os_.polygons, os_.bounds, 2.0, q
    if quick:
        return
    for folder in sorted(p.parent for p in maps.glob("*/scene-01.json")):
        name = f"map:{folder.name}"
        if wanted and name not in wanted and folder.name not in wanted:
            continue
        item = map_world(folder)
        if item is None:
            continue
        obs, bounds, radius, start, goal = item
        pm = PlanningMap(obs, robot_radius=radius, bounds=bounds)
        q = [(np.asarray(start, float), np.asarray(goal, float))] if start is not None else []
        span = min(bounds[2] - bounds[0], bounds[3] - bounds[1])
        q += _free_queries(pm, np.random.default_rng([seed, 11]), nq - len(q), min_dist=span / 2)
        yield name, obs, bounds, radius, q


def map_world(folder: Path):
    """True obstacles of a map's scene-01.json in metres, its bounds (the grid's cells), radius,
    start and goal; None when the folder lacks what is needed."""
    if not (folder / "workspace.toml").is_file():
        return None
    ws = load_workspace(folder)
    truth = json.loads((folder / "scene-01.json").read_text(encoding="utf-8"))
    floor = FloorSpec(**truth["params"]["floor"])
    polys = [Polygon(floor_to_world(floor, np.asarray(p, float), ws.pitch_m, ws.origin))
             for p in truth.get("obstacles_floor", truth["obstacles"])]
    corners = ws.lattice_to_world(np.array([[-0.5, -0.5], [floor.cols - 0.5, floor.rows - 0.5]]), floor.rows)
    bounds = (float(corners[:, 0].min()), float(corners[:, 1].min()), float(corners[:, 0].max()),
              float(corners[:, 1].max()))
    return polys, bounds, ws.robot_radius_m, ws.start_m, ws.goal_m


# -- measurement ---------------------------------------------------------------------------------
def _median_ms(v) -> float:
    return statistics.median(v) * 1e3 if v else math.nan


def measure_world(name, obs, bounds, radius, queries, *, planners, time_limit, n_ompl, seed) -> dict:
    build, cold, warm, lengths = [], [], [], []
    for s, g in queries:
        # Release the previous query's map and route before the clock starts: rebinding inside the
        # timed region made it pay for freeing them (5-9 us, 40 % of a straight-line query).
        pm = r = None
        t0 = time.perf_counter()
        pm = PlanningMap(obs, robot_radius=radius, bounds=bounds)
        t1 = time.perf_counter()
        r = pm.solve(s, g)
        t2 = time.perf_counter()
        build.append(t1 - t0)
        cold.append(t2 - t1)
        lengths.append(r.length)
    pm = PlanningMap(obs, robot_radius=radius, bounds=bounds)
    for s, g in queries:
        t0 = time.perf_counter()
        pm.solve(s, g)
        warm.append(time.perf_counter() - t0)
    # Replanning: a square (side 2 x radius, at least 1 % of the map) on the route's middle leg; the
    # robot is at the route's start.
    rep, rep_ok = [], 0
    side = max(2 * radius, 0.01 * max(bounds[2] - bounds[0], bounds[3] - bounds[1]))
    for s, g in queries:
        route = PlanningMap(obs, robot_radius=radius, bounds=bounds).solve(s, g)
        wp = route.waypoints
        k = (len(wp) - 1) // 2
        m = (wp[k] + wp[k + 1]) / 2
        new = box(m[0] - side / 2, m[1] - side / 2, m[0] + side / 2, m[1] + side / 2)
        if new.distance(LineString([s, s])) < side or new.distance(LineString([g, g])) < side:
            continue
        t0 = time.perf_counter()
        try:
            out = replan(route, s, [new])
        except PlanningError:
            continue
        rep.append(time.perf_counter() - t0)
        rep_ok += out.replanned
    row = {"world": name, "obstacles": len(obs), "queries": len(queries),
           "corners": int(pm.vmap.corners.shape[0]),
           "build_ms": _median_ms(build), "cold_ms": _median_ms(cold), "cold_p90_ms":
           float(np.percentile(cold, 90) * 1e3) if cold else math.nan,
           "cold_ms_ompl_queries": _median_ms(cold[:n_ompl]),
           "warm_ms": _median_ms(warm), "replan_ms": _median_ms(rep), "replans": len(rep), "replanned": rep_ok,
           "ompl": {}}
    for name_p in planners:
        ratios, times, fails = [], [], 0
        for qi, (s, g) in enumerate(queries[:n_ompl]):
            fresh = PlanningMap(obs, robot_radius=radius, bounds=bounds)
            r = None  # as above: the previous route is freed outside the timed region
            t0 = time.perf_counter()
            try:
                r = solve_ompl(fresh, s, g, name_p, time_limit=time_limit, seed=seed * 1000 + qi + 1)
            except PlanningError:
                fails += 1
                continue
            times.append(time.perf_counter() - t0)
            ratios.append(r.length / lengths[qi])
        row["ompl"][name_p] = {"solved": len(ratios), "failed": fails,
                               "mean_ratio": statistics.fmean(ratios) if ratios else math.nan,
                               "max_ratio": max(ratios) if ratios else math.nan,
                               "median_ms": _median_ms(times)}
    # OMPL's best planner on this world: the shortest mean length (then the fastest), and how much
    # slower it is than aux-corner's cold query on the same queries.
    done = [(o["mean_ratio"], o["median_ms"], p) for p, o in row["ompl"].items() if o["solved"] and not o["failed"]]
    if done:
        ratio, ms, best = min(done)
        row["best_ompl"] = {"planner": best, "mean_ratio": ratio, "median_ms": ms,
                            "speedup": ms / row["cold_ms_ompl_queries"]}
    # The hardest comparison: the fastest planner whose paths are within 0.1 % of the optimum on
    # average (no failure). BIT* stops as soon as its path meets the straight-line lower bound, so
    # where the queries are mostly straight lines it is both that fast and "equal" in length.
    near = [(o["median_ms"], p, o["mean_ratio"]) for p, o in row["ompl"].items()
            if o["solved"] and not o["failed"] and o["mean_ratio"] <= 1.001]
    if near:
        ms, fast, ratio = min(near)
        row["fastest_optimal_ompl"] = {"planner": fast, "mean_ratio": ratio, "median_ms": ms,
                                       "speedup": ms / row["cold_ms_ompl_queries"]}
    return row


def ompl_benchmark_log(name, obs, bounds, radius, query, planners, time_limit, path: Path) -> None:
    """Run ompl.tools.Benchmark on one query with aux-corner and the OMPL planners; save its log.

    It runs in a forked child that leaves with ``os._exit`` once the log is written: BIT* inside
    ompl.tools.Benchmark leaves C++ reference cycles that nanobind reports as leaks at interpreter
    exit (OMPL's, not sbplan's; the memory goes with the child).
    """
    ctx = mp.get_context("fork")
    proc = ctx.Process(target=_benchmark_child, args=(name, obs, bounds, radius, query, planners, time_limit, path))
    proc.start()
    proc.join()
    if proc.exitcode != 0 or not Path(path).is_file():
        raise PlanningError(f"--ompl-log: ompl.tools.Benchmark failed on {name} (exit code {proc.exitcode})")


def _benchmark_child(name, obs, bounds, radius, query, planners, time_limit, path) -> None:
    code = 1
    try:
        _run_benchmark(name, obs, bounds, radius, query, planners, time_limit, path)
        code = 0
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def _run_benchmark(name, obs, bounds, radius, query, planners, time_limit, path) -> None:
    pm = PlanningMap(obs, robot_radius=radius, bounds=bounds)
    ss = make_setup(pm)
    set_query(ss, query[0], query[1])
    bench = ot.Benchmark(ss, f"sbplan {name}")
    si = ss.getSpaceInformation()
    keep = [allocate(p, si, pm) for p in ("aux-corner", *planners)]
    for p in keep:
        bench.addPlanner(p)
    req = ot.Request(time_limit, 4096.0, 1, 0.05, False, False, True)
    bench.benchmark(req)
    tmp = Path(path).with_name(Path(path).name + ".part")
    bench.saveResultsToFile(str(tmp))
    os.replace(tmp, path)


def run(args: argparse.Namespace) -> int:
    quick = args.quick
    tl = args.time_limit if args.time_limit is not None else (0.2 if quick else 1.0)
    n_ompl = args.ompl_queries if args.ompl_queries is not None else (1 if quick else 3)
    planners = [p for p in args.planners.split(",") if p]
    for p in planners:
        if p not in OMPL_PLANNERS:
            raise InputError(f"--planners: unknown OMPL planner {p!r}; known: {', '.join(OMPL_PLANNERS)}")
    if tl <= 0 or n_ompl < 0 or (args.queries is not None and args.queries < 1):
        raise InputError("--time-limit must be > 0, --ompl-queries >= 0, --queries >= 1")
    from ..commands._progress import StderrProgress

    quiet(bool(getattr(args, "verbose", False)))
    rows, logs, notes = [], [], []
    progress = StderrProgress("bench plan")
    progress(0, 1, "building the worlds")
    all_worlds = list(worlds(args, args.seed, quick))
    if not any(w[0].startswith("map:") for w in all_worlds) and not quick:
        notes.append(f"no maps with scene-01.json + workspace.toml under {args.maps_dir}/: skipped")
    for k, (name, obs, bounds, radius, queries) in enumerate(all_worlds):
        progress(k, len(all_worlds), name)
        if not queries:
            notes.append(f"{name}: no solvable query found, skipped")
            continue
        rows.append(measure_world(name, obs, bounds, radius, queries, planners=planners, time_limit=tl,
                                  n_ompl=n_ompl, seed=args.seed))
        if args.ompl_log:
            base = Path(args.ompl_log)
            path = base if len(all_worlds) == 1 else base.with_name(
                f"{base.stem}-{name.replace(':', '-')}{base.suffix or '.log'}")
            ompl_benchmark_log(name, obs, bounds, radius, queries[0], planners, tl, path)
            logs.append(str(path))
    progress.close()
    if args.json:
        print(json.dumps({"rows": rows, "time_limit_s": tl, "seed": args.seed, "ompl_logs": logs,
                          "notes": notes}, indent=2))
        return 0
    print_table(rows, planners, tl, n_ompl, args.seed)
    for n in notes:
        print("note: " + n)
    for p in logs:
        print(f"wrote OMPL benchmark log {p}")
    return 0


def print_table(rows, planners, tl, n_ompl, seed) -> None:
    print(f"seed {seed}; OMPL planners: {tl:g} s per solve, simplified, first {n_ompl} queries of each world; "
          f"{platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}, "
          f"shapely {shapely.__version__}, OMPL {version('ompl')}")
    print()
    print("aux-corner (exact): median ms")
    hdr = f"{'world':22} {'obst':>5} {'corners':>7} {'queries':>7} {'build':>8} {'cold':>8} {'cold p90':>8} " \
          f"{'warm':>8} {'replan':>8}"
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        print(f"{r['world']:22} {r['obstacles']:>5} {r['corners']:>7} {r['queries']:>7} {r['build_ms']:>8.2f} "
              f"{r['cold_ms']:>8.2f} {r['cold_p90_ms']:>8.2f} {r['warm_ms']:>8.2f} {r['replan_ms']:>8.2f}")
    print()
    print("OMPL planners: path length / exact optimum (mean, max), failures, median ms; "
          "aux-corner: ratio 1 by definition")
    hdr = f"{'world':22} " + " ".join(f"{p:>24}" for p in planners)
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        cells = []
        for p in planners:
            o = r["ompl"][p]
            fail = f" {o['failed']}F" if o["failed"] else ""
            cells.append(f"{o['mean_ratio']:.3f}/{o['max_ratio']:.3f}{fail} {o['median_ms']:.0f}ms"
                         if o["solved"] else f"failed {o['failed']}")
        print(f"{r['world']:22} " + " ".join(f"{c:>24}" for c in cells))
    print()
    print("OMPL's best planner per world (shortest mean length, no failure), and the fastest within 0.1 % of the "
          "optimum, vs aux-corner's cold query on the same queries")
    hdr = f"{'world':22} {'best OMPL':>18} {'length':>7} {'OMPL ms':>8} {'aux ms':>7} {'speedup':>8}  " \
          f"{'fastest <= 1.001':>18} {'OMPL ms':>8} {'speedup':>8}"
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        b = r.get("best_ompl")
        if b is None:
            print(f"{r['world']:22} {'(every planner failed at least once)':>52}")
            continue
        line = f"{r['world']:22} {b['planner']:>18} {b['mean_ratio']:>7.3f} {b['median_ms']:>8.1f} " \
               f"{r['cold_ms_ompl_queries']:>7.2f} {b['speedup']:>7.0f}x"
        f = r.get("fastest_optimal_ompl")
        if f is not None:
            line += f"  {f['planner']:>18} {f['median_ms']:>8.1f} {f['speedup']:>7.0f}x"
        print(line)
