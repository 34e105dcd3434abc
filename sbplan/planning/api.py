"""The former home of the planning API, split into :mod:`.planning_map` (``PlanningMap``, ``TOL``),
:mod:`.route` (``Problem``, ``Route``) and :mod:`.plan_replan` (``plan``, ``replan``). Kept so that
``sbplan.planning.api`` imports keep working; import from :mod:`sbplan.planning` instead."""

from __future__ import annotations

from .plan_replan import plan, replan
from .planning_map import TOL, PlanningMap
from .route import Problem, Route

__all__ = ["TOL", "PlanningMap", "Problem", "Route", "plan", "replan"]
