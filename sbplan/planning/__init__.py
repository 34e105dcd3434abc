"""Routes around obstacles: the exact auxiliary-corner planner, OMPL planners, loaders.

``sbplan.plan(obstacles, start, goal, robot_radius=...)`` plans; ``sbplan.replan(route, position,
new_obstacles)`` updates a route. World frame: ``(x, y)``, x right, y up, metres (or pixels).
"""

from __future__ import annotations

from .api import Problem, PlanningMap, Route, plan, replan
from .loaders import ObstacleSet, load_obstacles

__all__ = ["Problem", "PlanningMap", "Route", "plan", "replan", "ObstacleSet", "load_obstacles"]
