"""The service's state: immutable values, replaced whole.

:class:`State` holds the current :class:`Snapshot` (one detection and the obstacles planned
around) and every :class:`RouteRecord`. Nothing in them is changed after it is built: a change
builds a new State, and :class:`sbplan.service.core.Service` swaps it in with one assignment. A
reader takes ``service.state`` once and sees the state before or after a change, never half of it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

from ..detection import Detection
from ..planning import Route
from . import models


def obstacle_key(polygon: Polygon) -> bytes:
    """What tells two obstacles apart from one frame to the next: the outline rounded to a
    micrometre. The same occupied cells give the same outline, so an obstacle that stays is never
    mistaken for a new one."""
    return np.round(np.asarray(polygon.exterior.coords, dtype=np.float64), 6).tobytes()


@dataclass(frozen=True, eq=False)
class Snapshot:
    """One detection made current.

    Attributes
    ----------
    frame : int
        1 for the first detection made current, +1 for each one after.
    detection : Detection
    result : dict
        ``detection.to_json()``, computed once.
    obstacles : tuple of shapely Polygon
        What routes are planned around, world metres (the MARs, or the outlines).
    keys : frozenset of bytes
        :func:`obstacle_key` of each obstacle.
    bounds : (xmin, ymin, xmax, ymax)
        The floor the grid covers, metres.
    received : float
        When the frame arrived, seconds since the epoch.
    source, name : str, str or None
        ``"post"`` or the live source; the frame's file name.
    """

    frame: int
    detection: Detection
    result: dict
    obstacles: tuple[Polygon, ...]
    keys: frozenset[bytes]
    bounds: tuple[float, float, float, float]
    received: float
    source: str
    name: str | None = None
    #: what GET /state answers (age_s 0: set per request), validated once off the event loop
    model: models.State | None = field(default=None, repr=False)
    #: exports computed on first request (GeoJSON, nav2 map): a pure function of the snapshot, so
    #: two requests computing one at once store the same value
    cache: dict[str, Any] = field(default_factory=dict, repr=False)

    def info(self) -> dict:
        return {"frame": self.frame, "received": self.received, "source": self.source, "name": self.name}


@dataclass(frozen=True, eq=False)
class RouteRecord:
    """One route the service keeps, and what it needs to replan it.

    ``route`` is None while the route is blocked (``model.state == "blocked"``). ``position`` is
    the robot's last reported position (the start at first): a route a new obstacle blocks is
    replanned from there. ``planned_on`` are the keys of the obstacles the current route is known
    to keep clear of; an obstacle of a later frame that is not among them is new to this route.
    """

    model: models.Route
    route: Route | None
    goal: tuple[float, float]
    position: tuple[float, float]
    robot_radius: float
    margin: float
    extras: tuple[Polygon, ...]
    planned_on: frozenset[bytes]

    @property
    def id(self) -> str:
        return self.model.id

    @property
    def owner(self) -> str | None:
        return self.model.owner

    def blocked_by(self, obstacles: list[Polygon]) -> bool:
        """Whether any of ``obstacles`` comes closer than the robot's clearance to what is left of
        the route (from the last reported position on)."""
        if not obstacles:
            return False
        if self.route is None:
            return True
        rest = remaining(self.route.waypoints, np.asarray(self.position, dtype=np.float64))
        line = LineString(rest) if len(rest) >= 2 else shapely.Point(rest[0])
        distances = shapely.distance(line, np.asarray(obstacles, dtype=object))
        return bool((distances < self.robot_radius + self.margin).any())

    def evolve(self, **changes: Any) -> "RouteRecord":
        return replace(self, **changes)


def remaining(waypoints: np.ndarray, position: np.ndarray) -> np.ndarray:
    """The part of a route still ahead of a robot at ``position``: ``position``, then the
    waypoints after the leg nearest to it. ``waypoints`` (M, 2), ``position`` (2,); returns (K, 2)."""
    wp = np.asarray(waypoints, dtype=np.float64)
    if len(wp) < 2:
        return np.vstack([position, wp[-1:]]) if len(wp) else position[None]
    a, b = wp[:-1], wp[1:]
    d = b - a
    t = np.clip(((position - a) * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0.0, 1.0)
    i = int(np.argmin(np.hypot(*(a + t[:, None] * d - position).T)))
    return np.vstack([position[None], wp[i + 1:]])


@dataclass(frozen=True, eq=False)
class State:
    """The whole state: the current snapshot (None before the first detection) and the routes,
    least recently changed first."""

    snapshot: Snapshot | None = None
    routes: Mapping[str, RouteRecord] = field(default_factory=lambda: MappingProxyType({}))

    def routes_copy(self) -> dict[str, RouteRecord]:
        """The routes as a new dict, to build the next state from. (A mappingproxy's copy()
        copies the dict under it at once; dict(proxy) goes key by key: 0.1 ms for 1024 routes,
        on every route request.)"""
        routes = self.routes
        return routes.copy() if isinstance(routes, MappingProxyType) else dict(routes)

    def with_routes(self, routes: dict[str, RouteRecord], snapshot: Snapshot | None = None) -> "State":
        """A new state with these routes (the dict is handed over: the caller must not keep it)."""
        return State(self.snapshot if snapshot is None else snapshot, MappingProxyType(routes))


def route_model(*, rid: str, owner: str | None, version: int, frame: int, reason: str, route: Route | None,
                start: tuple[float, float], goal: tuple[float, float], position: tuple[float, float],
                robot_radius: float, margin: float, extras: int, planner: str,
                error: models.Error | None = None) -> models.Route:
    """The route as clients see it."""
    if route is None:
        status, length, waypoints, ms = None, None, [], 0.0
    else:
        # micrometres, as the detection JSON: the planner's clearance has 1e-6 of the floor's size to spare
        status, length, ms = route.status, round(route.length, 6), round(route.time_s * 1e3, 3)
        waypoints = [(x, y) for x, y in np.round(route.waypoints, 6).tolist()]
        planner = route.planner
    return models.Route.model_construct(
        id=rid, owner=owner, version=version, frame=frame, state="ok" if route is not None else "blocked",
        reason=reason, status=status, length_m=length, waypoints_m=waypoints, start_m=tuple(start),
        goal_m=tuple(goal), position_m=tuple(position), robot_radius_m=robot_radius, margin_m=margin,
        extra_obstacles=extras, planner=planner, planning_ms=ms, updated=time.time(), error=error)

