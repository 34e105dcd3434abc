"""What every planner takes and gives: a :class:`Problem` (a query on a map) and a :class:`Route`.

World frame: ``(x, y)`` in metres (or pixels), x to the right, y up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .planning_map import PlanningMap

_F64 = np.dtype(float)

#: The ``format`` of a route's JSON (``Route.to_dict``, ``sbplan plan --json``, the demo's route.json).
ROUTE_FORMAT = "sbplan.route/1"


@dataclass
class Problem:
    """A query on a map: what a planner stage's ``solve`` receives.

    Attributes
    ----------
    map : PlanningMap
    start, goal : ndarray of shape (2,), ``(x, y)``
    """

    map: PlanningMap
    start: np.ndarray
    goal: np.ndarray


@dataclass
class Route:
    """A planned route.

    Attributes
    ----------
    waypoints : ndarray of shape (M, 2), ``(x, y)``
    length : float
    status : "exact" | "approximate"
        approximate: the start or goal had to escape from within the clearance of an obstacle, or
        a sampling planner returned an approximate solution.
    planner : str
        The name of the planner stage that made it (``replan`` plans with the same one).
    time_s : float, seconds spent planning
    replanned : bool
        True only for a route ``replan`` planned anew; False for a fresh ``plan`` and for the
        remaining route ``replan`` returned unchanged (no new obstacle touched it).
    map : PlanningMap or None
        The map it was planned on (``replan`` copies it).
    goal : ndarray of shape (2,)
        The goal asked for (the last waypoint).
    """

    waypoints: np.ndarray
    status: str = "exact"
    planner: str = "aux-corner"
    time_s: float = 0.0
    replanned: bool = False
    map: PlanningMap | None = field(default=None, repr=False, compare=False)
    goal: np.ndarray | None = field(default=None, repr=False, compare=False)
    length: float = field(init=False)

    def __post_init__(self) -> None:
        w = self.waypoints
        if not (type(w) is np.ndarray and w.dtype is _F64 and w.ndim == 2 and w.shape[1] == 2):
            w = self.waypoints = np.asarray(w, float).reshape(-1, 2)
        # Plain Python over the waypoints: numpy's call overhead showed on straight-line queries.
        pts = w.tolist()
        length = 0.0
        for (x0, y0), (x1, y1) in zip(pts, pts[1:]):
            length += math.hypot(x1 - x0, y1 - y0)
        self.length = length
        if self.goal is None and pts:
            self.goal = w[-1].copy()

    @classmethod
    def segment(cls, sx: float, sy: float, gx: float, gy: float, *, planner: str, map: PlanningMap | None,
                goal: np.ndarray) -> "Route":
        """The exact route (sx, sy) -> (gx, gy) along one segment, ``time_s`` 0: what ``Route(((sx,
        sy), (gx, gy)), planner=planner, map=map, goal=goal)`` builds, the same length (one
        hypot, as in __post_init__), without the dataclass machinery (straight-line queries,
        where it showed)."""
        r = cls.__new__(cls)
        r.waypoints = np.array(((sx, sy), (gx, gy)))
        r.status, r.planner, r.time_s, r.replanned, r.map, r.goal = "exact", planner, 0.0, False, map, goal
        r.length = math.hypot(gx - sx, gy - sy)
        return r

    def to_dict(self) -> dict:
        """The route's JSON (``sbplan.route/1``: ``sbplan plan --json``, the demo's route.json)."""
        return {"format": ROUTE_FORMAT, "status": self.status, "planner": self.planner, "length": self.length,
                "time_s": self.time_s, "replanned": self.replanned,
                "waypoints": self.waypoints.tolist()}
