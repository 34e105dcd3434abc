"""Routes around obstacles: the exact auxiliary-corner planner, OMPL planners, loaders.

``sbplan.plan(obstacles, start, goal, robot_radius=...)`` plans; ``sbplan.replan(route, position,
new_obstacles)`` updates a route. World frame: ``(x, y)``, x right, y up, metres (or pixels).

Modules: ``planning_map`` (PlanningMap: one map, its enlarged obstacles and visibility cache),
``route`` (Problem, Route), ``aux_corner`` (the exact planner), ``ompl_planners`` (OMPL's),
``plan_replan`` (plan, replan, the shared map cache), ``vismap`` (the visibility graph and its
search), ``loaders`` (obstacles from files and detections), ``geometry``, ``plot``.
"""

from __future__ import annotations

from .loaders import ObstacleSet, detection_obstacles, load_obstacles
from .plan_replan import plan, replan
from .planning_map import PlanningMap
from .route import Problem, Route

__all__ = ["Problem", "PlanningMap", "Route", "plan", "replan", "ObstacleSet", "load_obstacles",
           "detection_obstacles"]
