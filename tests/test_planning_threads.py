"""Planning from several threads at once (the TUI's workers, a service's requests): every route
equals the one a single thread gets.

What the threads share: ``plan``'s map cache (sbplan.planning.plan_replan.MAPS), the cached maps'
visibility caches (filled by the searches, copied by ``replan``) and OMPL's process-wide random
number generator. Python switches threads every few milliseconds by default; the tests switch
every microsecond, so that the threads interleave inside those updates.
"""

from __future__ import annotations

import sys
import threading

import numpy as np
import pytest
from shapely.geometry import box

import sbplan
from sbplan import registry
from sbplan.errors import PlanningError
from sbplan.planning import PlanningMap
from sbplan.planning.plan_replan import MAPS

from test_planning_replan import rect_world

B = (0.0, 0.0, 100.0, 100.0)
THREADS, TASKS = 4, 20


def tasks(seed: int) -> list[tuple]:
    """Plans (given bounds: a few cached maps; no bounds: a map per query, more maps than the
    cache keeps) and replans (a square on the route's middle leg, the robot a third along)."""
    rng = np.random.default_rng(seed)
    worlds = [rect_world(s, 25) for s in (1, 2, 3)]
    out = []
    while len(out) < THREADS * TASKS:
        w = int(rng.integers(len(worlds)))
        s, g = rng.uniform(5, 95, (2, 2))
        if PlanningMap(worlds[w], robot_radius=0.5, bounds=B).vmap.covered(np.stack([s, g])).any():
            continue
        kind = ("plan", "plan-unbounded", "replan")[len(out) % 3]
        out.append((kind, worlds[w], s, g))
    return out


def run(task) -> tuple:
    """One task's answer as plain data: (status, planner, replanned, waypoints) or the error."""
    kind, obs, s, g = task
    try:
        route = sbplan.plan(obs, s, g, robot_radius=0.5, bounds=None if kind == "plan-unbounded" else B)
        if kind == "replan":
            wp = route.waypoints
            k = (len(wp) - 1) // 2
            m = (wp[k] + wp[k + 1]) / 2
            pos = wp[0] + (wp[1] - wp[0]) / 3
            route = sbplan.replan(route, pos, [box(m[0] - 1.5, m[1] - 1.5, m[0] + 1.5, m[1] + 1.5)])
    except PlanningError as e:
        return (type(e).__name__, str(e))
    return (route.status, route.planner, route.replanned, route.waypoints.tolist())


def run_threads(work: list[list], fn) -> list[list]:
    """Run fn on every item of work[i] in thread i, all threads released together."""
    barrier = threading.Barrier(len(work))
    results: list[list] = [[] for _ in work]
    errors: list[BaseException] = []

    def worker(i: int) -> None:
        try:
            barrier.wait()
            results[i] = [fn(item) for item in work[i]]
        except BaseException as exc:  # reported below: an exception in a thread must fail the test
            errors.append(exc)

    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    try:
        threads = [threading.Thread(target=worker, args=(i,)) for i in range(len(work))]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        sys.setswitchinterval(old)
    if errors:
        raise errors[0]
    return results


@pytest.mark.parametrize("seed", [0, 1])
def test_plans_and_replans_from_threads_equal_one_thread(seed):
    todo = tasks(seed)
    MAPS.clear()
    expected = [run(t) for t in todo]
    assert sum(e[0] == "exact" for e in expected) > len(todo) // 2  # mostly real routes, few errors
    # Each thread gets a share of the tasks in its own order, on caches filled in a different order.
    rng = np.random.default_rng(seed + 10)
    order = rng.permutation(len(todo))
    shares = [order[i::THREADS].tolist() for i in range(THREADS)]
    MAPS.clear()
    got = run_threads([[todo[k] for k in share] for share in shares], run)
    for share, answers in zip(shares, got):
        assert len(answers) == len(share)
        for k, answer in zip(share, answers):
            assert answer == expected[k], f"task {k} ({todo[k][0]})"
    assert len(MAPS) == MAPS.size  # the unbounded plans made the cache evict maps meanwhile


def test_queries_on_one_shared_map_from_threads_equal_one_thread():
    """One PlanningMap shared by the threads, searches filling its cache while others copy it."""
    obs = rect_world(4, 40)
    todo = [t for t in tasks(2) if t[0] != "plan-unbounded"][:THREADS * TASKS // 2]

    def answer(pm, task):
        kind, _, s, g = task
        try:
            route = pm.solve(s, g)
            if kind == "replan":
                route = sbplan.replan(route, s, [box(g[0] - 6, g[1] - 6, g[0] - 3, g[1] - 3)])
        except PlanningError as e:
            return (type(e).__name__, str(e))
        return (route.status, route.replanned, route.waypoints.tolist())

    fresh = PlanningMap(obs, robot_radius=0.5, bounds=B)
    expected = [answer(fresh, t) for t in todo]
    shared = PlanningMap(obs, robot_radius=0.5, bounds=B)
    shares = [list(range(i, len(todo), THREADS)) for i in range(THREADS)]
    got = run_threads([[todo[k] for k in share] for share in shares], lambda t: answer(shared, t))
    for share, answers in zip(shares, got):
        for k, a in zip(share, answers):
            assert a == expected[k], f"task {k}"


def test_seeded_ompl_solves_from_threads_equal_one_thread():
    """OMPL's generator is one per process: each seeded solve gets its own seed's route."""
    obs = [box(40, 20, 60, 80), box(20, 0, 25, 40), box(70, 50, 75, 100)]
    seeds = list(range(1, 9))

    def solve(seed):
        stage = registry.planner("rrt-connect", seed=seed)
        return sbplan.plan(obs, (10, 50), (90, 50), robot_radius=1.0, bounds=B, planner=stage,
                           time_limit=1.0).waypoints.tolist()

    expected = {s: solve(s) for s in seeds}
    assert len({str(v) for v in expected.values()}) > 1  # the seeds do give different routes
    got = run_threads([seeds[i::THREADS] for i in range(THREADS)], lambda s: (s, solve(s)))
    for answers in got:
        for s, wp in answers:
            assert wp == expected[s], f"seed {s}"
