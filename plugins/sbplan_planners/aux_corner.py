"""The auxiliary-corner planner stage: exact shortest routes on a lazy visibility graph."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from sbplan.contracts import Planner


@dataclass(kw_only=True, frozen=True)
class AuxCornerPlanner(Planner):
    name: ClassVar[str] = "aux-corner"
    description: ClassVar[str] = "exact shortest route: lazy A* over the enlarged obstacles' convex corners"
    guarantee: ClassVar[str] = "proven shortest for the robot's radius"
    exact: ClassVar[bool] = True

    def solve(self, problem, *, time_limit: float = 1.0):
        return problem.map.solve(problem.start, problem.goal, time_limit=time_limit, planner=self.name)
