"""OMPL's sampling-based planners as sbplan planner stages, on the same obstacles as aux-corner
(exact motion validator, fresh optimization objective per solve): each a thin stage around
``sbplan.planning.ompl_planners.solve_ompl``, as ``AuxCornerPlanner`` is around
``solve_aux_corner``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from sbplan.contracts import Planner, option
from sbplan.errors import InputError
from sbplan.planning.route import Problem, Route


@dataclass(kw_only=True, frozen=True)
class _OmplPlanner(Planner):
    seed: int = option(1, "seed of OMPL's random number generator, >= 1 (-1: not seeded)")
    simplify: bool = option(True, "shorten the found path with OMPL's simplifier")

    def __post_init__(self) -> None:
        if not isinstance(self.seed, int) or self.seed == 0 or self.seed < -1:
            raise InputError(f"option seed: expected an integer >= 1 (or -1), got {self.seed!r}")

    def solve(self, problem: Problem, *, time_limit: float = 1.0) -> Route:
        # Imported here, not at the top: importing OMPL costs ~30 ms, and building the stage
        # registry (every sbplan command) must not pay it.
        from sbplan.planning.ompl_planners import solve_ompl

        return solve_ompl(problem.map, problem.start, problem.goal, self.name, time_limit=time_limit,
                          simplify=self.simplify, seed=None if self.seed < 0 else self.seed)


#: What a sampling planner's route is sure to be: the motion validator is exact, the search is not.
# (no route within the time limit does not mean there is none: NoRouteError says so)
_FEASIBLE = "collision-free, not shortest"
_NEAR_SHORTEST = "collision-free, near-shortest, not proven"


def _make(stage_name: str, ompl_name: str, what: str, guarantee: str) -> type:
    cls = type(f"Ompl{ompl_name}", (_OmplPlanner,), {
        "__module__": __name__,
        "__annotations__": {"name": "ClassVar[str]", "aliases": "ClassVar[tuple[str, ...]]",
                            "description": "ClassVar[str]", "guarantee": "ClassVar[str]"},
        "name": stage_name,
        # OMPL's own class name finds the stage too (sbplan plan --planner RRTstar)
        "aliases": (ompl_name,),
        "description": f"OMPL {ompl_name}: {what}",
        "guarantee": guarantee,
    })
    return dataclass(kw_only=True, frozen=True)(cls)


STAGES = [
    _make("rrt-connect", "RRTConnect", "bidirectional RRT, fast, not optimal (simplified)", _FEASIBLE),
    _make("rrt-star", "RRTstar", "asymptotically optimal RRT", _NEAR_SHORTEST),
    _make("informed-rrt-star", "InformedRRTstar", "RRT* sampling an informed ellipse once solved", _NEAR_SHORTEST),
    _make("prm-star", "PRMstar", "asymptotically optimal probabilistic roadmap", _NEAR_SHORTEST),
    _make("bit-star", "BITstar", "batch informed trees, asymptotically optimal", _NEAR_SHORTEST),
    _make("fmt-star", "FMT", "fast marching tree, asymptotically optimal", _NEAR_SHORTEST),
]
