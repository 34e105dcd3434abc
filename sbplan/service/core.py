"""The service's workspace: one calibration, its detector, the current state and the routes.

Threads, and why:

- **the detection thread** (one): a :class:`~sbplan.detection.Detector` keeps the camera's last
  pose to register the next frame, so frames are decoded and detected one at a time, in order.
- **the state thread** (one): makes a detection current (and replans the routes it blocks),
  plans routes (unless planning processes do), replans and deletes them. Each change builds a
  new immutable :class:`~sbplan.service.state.State` and swaps it in with one assignment, so a
  reader (any thread) sees the state before or after a change, never half of it. Every change
  holds the service's write lock, so a change that reads the state and writes it back cannot
  interleave with another. The state thread takes the lock for each of its changes; the event
  loop takes it only without waiting, to record a route a planning process planned (a few dozen
  microseconds, no planning: handing that to the state thread cost more than doing it, the two
  threads passing the GIL back and forth), and leaves it to the state thread when a change is
  running. Planning on one map stays on one thread: a map's visibility cache fills lazily.
- **the planning processes** (``planner_processes``, :mod:`.workers`): plan ``POST /routes``
  queries on every core, each with its own copy of the current frame's maps; they keep no state
  that matters.
- the caller's threads (the event loop, a live source's reader) read ``state`` and wait on the
  threads and processes above. The CPU-heavy work (decoding, detection, planning, building a
  map) never runs on the event loop.

Events (new detections, route changes, rejected frames) are numbered by the writer that makes
the change, in the order they happen, and handed to the listeners (the WebSocket broker) as
:class:`OutEvent`, serialized to JSON text once, when a listener first reads it.

A live source hooks in with :meth:`process_frame` (an image in, detection and commit done) or,
when it detects itself, :meth:`commit_detection`; its own events go out through :meth:`publish`.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from pydantic import BaseModel
from shapely.geometry import Polygon

from .. import __version__, registry
from ..detection import Calibration, Detection, Detector
from ..errors import InputError, SbplanError
from ..detection.obstacles import DEFAULT_OBSTACLE_MODEL, OBSTACLE_MODELS
from ..planning import PlanningMap, detection_obstacles, plan
from . import images, models
from .errors import BusyError, NoFrameError, UnknownRouteError, status_and_code
from .state import RouteRecord, Snapshot, State, obstacle_key, route_model
from ..planning.plan_replan import MapCache
from .workers import MAPS_KEPT, PlannerPool, prepared_map



class OutEvent:
    """An event on its way to the WebSocket clients: ``text`` is its JSON; ``owner`` is set for a
    route's events (only that owner's subscribers and the unfiltered ones get them).

    Given ``model`` (an event model class) and ``fields`` instead of ``text``, the event is built
    and serialized on the first read of ``text``, once: with nobody subscribed it never is (every
    route request makes an event; serializing it cost a tenth of the request's CPU)."""

    __slots__ = ("seq", "type", "owner", "_text", "_model", "_fields")

    def __init__(self, seq: int, type: str, text: str | None = None, owner: str | None = None, *,
                 model: type[BaseModel] | None = None, fields: dict | None = None):
        if (text is None) == (model is None):
            raise ValueError("OutEvent: give text, or model and fields")
        self.seq, self.type, self.owner = seq, type, owner
        self._text, self._model, self._fields = text, model, fields

    @property
    def text(self) -> str:
        # two threads reading it at once both build the same string: no lock needed
        if self._text is None:
            assert self._model is not None  # one of the two was given
            self._text = self._model(seq=self.seq, **(self._fields or {})).model_dump_json()
        return self._text

    def __repr__(self) -> str:
        return f"OutEvent(seq={self.seq}, type={self.type!r}, owner={self.owner!r})"


@dataclass(frozen=True)
class Limits:
    """What one request may carry. ``max_body`` bytes for a frame (``max_json`` for anything
    else), ``max_pixels`` for an image (read from its header before decoding); at most
    ``max_pending_frames`` posted frames wait for detection at once (each holds its bytes)."""

    max_body: int = 32 * 2**20
    max_json: int = 64 * 2**10
    max_pixels: int = 40_000_000
    max_pending_frames: int = 4


class Service:
    """One workspace served: the calibration, the current state, the routes.

    Parameters
    ----------
    calibration : Calibration
    use : "mar", "parts" or "outline"
        The obstacle model the service plans around (and serves as GeoJSON and nav2): the
        obstacles' minimum-area rectangles, the rectangles of their parts (default) or their
        outlines (:mod:`sbplan.detection.obstacles`).
    planner : str
        Planner stage for new routes (``sbplan plugins``); default the exact ``aux-corner``.
    time_limit : float
        Seconds one planning query may take.
    max_routes : int
        Routes kept; beyond it the least recently changed one is dropped.
    limits : Limits
    planner_processes : int
        Processes that plan ``POST /routes`` queries (:mod:`.workers`), one per core but one is best (:func:`.workers.default_processes`); 0
        (default): the state thread plans them. Replans always run on the state thread.
    """

    def __init__(self, calibration: Calibration, *, use: str = DEFAULT_OBSTACLE_MODEL, planner: str = "aux-corner",
                 time_limit: float = 1.0, max_routes: int = 256, limits: Limits = Limits(),
                 detector: Detector | None = None, planner_processes: int = 0):
        if use not in OBSTACLE_MODELS:
            raise InputError(f"use: expected one of {', '.join(OBSTACLE_MODELS)}, got {use!r}")
        if max_routes < 1:
            raise InputError(f"max_routes: must be >= 1, got {max_routes}")
        if not time_limit > 0:
            raise InputError(f"time_limit: must be > 0 seconds, got {time_limit!r}")
        registry.planner(planner)  # an unknown name fails here, not on every request
        self.calibration = calibration
        self.detector = detector or Detector(calibration)
        self.use, self.planner, self.time_limit, self.max_routes = use, planner, float(time_limit), int(max_routes)
        self.limits = limits
        self.bounds = tuple(float(v) for v in calibration.world_bounds())
        self.version = __version__
        self.source_name: str | None = None
        self._state = State()
        self._detect_pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="sbplan-detect")
        self._state_pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="sbplan-state")
        # Held by every change (see the module's docstring); _writer: the thread holding it.
        self._write_lock = threading.Lock()
        self._writer: int | None = None
        self._route_ids = itertools.count(1)
        self._maps = MapCache(MAPS_KEPT)  # used on the state thread only
        self._seq = 0
        self._pending = 0
        self._listeners: list[Callable[[OutEvent], None]] = []
        # route requests (POST /routes) planned in processes of their own: see .workers
        self._planners = PlannerPool(planner_processes) if planner_processes > 0 else None

    # -- reading ----------------------------------------------------------------------------------
    @property
    def state(self) -> State:
        """The current state (immutable; take it once per request)."""
        return self._state

    def snapshot(self) -> Snapshot:
        """The current snapshot, or NoFrameError before the first detection."""
        snap = self._state.snapshot
        if snap is None:
            raise NoFrameError("no frame detected yet: POST /detect an image, or start the service with --source")
        return snap

    def route(self, rid: str) -> RouteRecord:
        rec = self._state.routes.get(rid)
        if rec is None:
            raise UnknownRouteError(f"no route {rid!r} (unknown, deleted, or dropped: the service keeps the "
                                    f"{self.max_routes} most recently changed routes)")
        return rec

    # -- events -----------------------------------------------------------------------------------
    def add_listener(self, listener: Callable[[OutEvent], None]) -> None:
        """``listener(event)`` is called for every event by the writer that made it (the state
        thread, or the event loop recording a route); it must not block."""
        self._listeners.append(listener)

    def remove_listener(self, listener: Callable[[OutEvent], None]) -> None:
        if listener in self._listeners:
            self._listeners.remove(listener)

    def publish(self, model: type[BaseModel], owner: str | None = None, **fields: Any) -> concurrent.futures.Future:
        """Number and send an event of class ``model`` from any thread (a live source's own events)."""
        return self._state_submit(self._emit, model, owner, fields)

    def _emit(self, model: type[BaseModel], owner: str | None, fields: dict) -> None:
        self._check_thread()
        self._seq += 1
        if not self._listeners:
            return
        kind = model.model_fields["type"].default  # every event model has its `type` tag (models.Event)
        out = OutEvent(self._seq, kind, owner=owner, model=model, fields=fields)
        for listener in list(self._listeners):
            listener(out)

    # -- frames -----------------------------------------------------------------------------------
    def process_frame(self, image: Any, *, source: str = "post", name: str | None = None) -> Snapshot:
        """Detect an image (grayscale array, or PNG/JPEG bytes) and make it the current state;
        blocks until done. Raises what detection raises (the frame is then rejected and a
        ``frame-rejected`` event sent)."""
        return self.submit_frame(image, source=source, name=name).result()[0]

    def submit_frame(self, image: Any, *, source: str = "post", name: str | None = None,
                     received: float | None = None) -> concurrent.futures.Future:
        """:meth:`process_frame` without waiting: a future of ``(snapshot, replanned route ids)``."""
        received = time.time() if received is None else received
        done: concurrent.futures.Future = concurrent.futures.Future()

        def detect() -> None:
            try:
                gray = self._decode(image) if isinstance(image, (bytes, bytearray, memoryview, _Encoded)) else image
                detection = self.detector(gray)
                staged = self._stage(detection, source=source, name=name, received=received)
            except BaseException as exc:  # noqa: BLE001  (handed to the waiting request)
                if isinstance(exc, SbplanError):
                    _, code = status_and_code(exc)
                    self.publish(models.FrameRejectedEvent, source=source, name=name, code=code, message=str(exc))
                done.set_exception(exc)
                return
            # submitted from this thread, in detection order: frames are made current in order
            try:
                commit = self._state_submit(self._commit, staged)
            except RuntimeError as exc:  # shutting down
                done.set_exception(exc)
                return
            commit.add_done_callback(lambda f: _chain(f, done))

        self._detect_pool.submit(detect)
        return done

    async def detect(self, data: bytes, *, source: str = "post") -> tuple[Snapshot, list[str]]:
        """Async :meth:`submit_frame` for the event loop: PNG or JPEG bytes."""
        size = images.check_size(data, max_pixels=self.limits.max_pixels, expected=self.calibration.image_shape)
        # the count is only touched on the event loop: no lock
        if self._pending >= self.limits.max_pending_frames:
            raise BusyError(f"{self._pending} frames are waiting for detection; send this one again later")
        self._pending += 1
        try:
            return await asyncio.wrap_future(self.submit_frame(_Encoded(bytes(data), size), source=source))
        finally:
            self._pending -= 1

    def _decode(self, data: Any) -> np.ndarray:
        if isinstance(data, _Encoded):
            return images.decode(data.data, data.size)
        size = images.check_size(bytes(data), max_pixels=self.limits.max_pixels, expected=self.calibration.image_shape)
        return images.decode(bytes(data), size)

    def commit_detection(self, detection: Detection, *, source: str, name: str | None = None,
                         received: float | None = None) -> tuple[Snapshot, list[str]]:
        """Make a detection made elsewhere (a live source's) current; blocks until done."""
        staged = self._stage(detection, source=source, name=name, received=time.time() if received is None else received)
        return self._state_submit(self._commit, staged).result()

    def _stage(self, detection: Detection, *, source: str, name: str | None, received: float) -> dict:
        """The work of making a snapshot that needs no state (runs on the detection thread)."""
        found = detection_obstacles(detection, use=self.use, source=source)
        obstacles = tuple(part for poly in found.polygons for part in _parts(poly))
        result = detection.to_json()
        return dict(detection=detection, result=result, checked=models.DetectionResult.model_validate(result),
                    obstacles=obstacles,
                    keys=frozenset(obstacle_key(p) for p in obstacles),
                    bounds=self.bounds, received=received, source=source, name=name)

    def _commit(self, staged: dict) -> tuple[Snapshot, list[str]]:
        """Make a staged detection current, replan the routes its new obstacles block, swap the
        state once, then send the events (state thread)."""
        self._check_thread()
        old = self._state
        frame = old.snapshot.frame + 1 if old.snapshot is not None else 1
        staged = dict(staged)
        checked = staged.pop("checked")
        info = dict(frame=frame, received=staged["received"], source=staged["source"], name=staged["name"])
        snap = Snapshot(frame=frame, model=models.State.model_construct(**dict(checked), **info, age_s=0.0), **staged)
        changed: list[RouteRecord] = []
        routes = old.routes_copy()
        if old.snapshot is None or snap.keys != old.snapshot.keys:
            for rid, rec in old.routes.items():
                new = self._check_route(rec, snap)
                if new is not rec:
                    routes[rid] = new
                    if new.model is not rec.model:
                        changed.append(new)
        for rec in changed:  # changed routes are the most recently changed
            routes[rec.id] = routes.pop(rec.id)
        self._state = old.with_routes(routes, snapshot=snap)
        d, r = snap.detection, snap.result
        self._emit(models.DetectionEvent, None, dict(
            **snap.info(), occupied_cells=[tuple(c) for c in r["occupied_cells"]],
            obstacles=[dict(id=o["id"], cells=o["cells"], mar_m=o.get("mar_m"), outline_m=o.get("outline_m"))
                       for o in r["obstacles"]],
            camera=r["camera"], symbols_found=d.symbols_found, symbols_expected=d.symbols_expected))
        for rec in changed:
            self._emit(models.RouteEvent, rec.owner, dict(route=rec.model))
        return snap, [rec.id for rec in changed]

    def _check_route(self, rec: RouteRecord, snap: Snapshot) -> RouteRecord:
        """The route after a new frame: the same model when no new obstacle blocks it, else
        replanned from the last reported position (or marked blocked when no route is left)."""
        if rec.route is None:  # blocked: the obstacles changed, so try again
            return self._replanned(rec, snap, rec.position, rec.extras, reason="blocked", raise_errors=False)
        new = [p for p in snap.obstacles if obstacle_key(p) not in rec.planned_on]
        if not rec.blocked_by(new):
            # the route keeps clear of every current obstacle: the old ones by construction, the
            # new ones just checked
            return rec if rec.planned_on >= snap.keys else rec.evolve(planned_on=rec.planned_on | snap.keys)
        return self._replanned(rec, snap, rec.position, rec.extras, reason="blocked", raise_errors=False)

    # -- routes -----------------------------------------------------------------------------------
    async def create_route(self, request: models.RouteRequest) -> models.Route:
        pool = self._planners
        if pool is None or not pool.alive:
            return await asyncio.wrap_future(self._state_submit(self._create_route, request))
        # planned in a planning process, recorded on the state thread
        snap = self.snapshot()
        radius = self._radius(request.robot_radius)
        route = await pool.plan(snap.frame, snap.obstacles, snap.bounds, radius=radius, margin=float(request.margin),
                                start=request.start, goal=request.goal, planner=self.planner,
                                time_limit=self.time_limit)
        # Recording it is quick (no planning, unless a newer frame came meanwhile): done here
        # when no change is running, else on the state thread. Handing it over costs more than
        # the record itself: the two threads then pass the GIL back and forth.
        if self._write_lock.acquire(blocking=False):
            try:
                if self._state.snapshot is snap:
                    self._writer = threading.get_ident()
                    return self._add_route(request, snap, radius, route)
            finally:
                self._writer = None
                self._write_lock.release()
        return await asyncio.wrap_future(self._state_submit(self._add_route, request, snap, radius, route))

    async def replan_route(self, rid: str, request: models.ReplanRequest) -> models.Route:
        return await asyncio.wrap_future(self._state_submit(self._replan_route, rid, request))

    async def delete_route(self, rid: str) -> None:
        await asyncio.wrap_future(self._state_submit(self._delete_route, rid))

    def set_position(self, rid: str, position: tuple[float, float]) -> concurrent.futures.Future:
        """Record where a route's robot is (the next replan because of a new obstacle starts there)."""
        return self._state_submit(self._set_position, rid, position)

    def _radius(self, value: float | None) -> float:
        if value is not None:
            return float(value)
        return float(self.calibration.workspace.robot_radius_m)

    def _plan(self, snap: Snapshot, extras: tuple[Polygon, ...], start, goal, radius: float, margin: float):
        if extras:  # a route's own obstacles: plan()'s cache keeps the few maps such routes need
            obstacles: Any = list(snap.obstacles) + list(extras)
        else:
            obstacles = self._map(snap, radius, margin)
        return plan(obstacles, start, goal, robot_radius=radius, margin=margin, planner=self.planner,
                    bounds=snap.bounds, time_limit=self.time_limit)

    def _map(self, snap: Snapshot, radius: float, margin: float) -> PlanningMap:
        """The snapshot's planning map for a robot size, built once and kept for the next queries
        (its visibility cache fills as they come): plan() given a list of polygons would check and
        hash all of them again on every request."""
        if self._planners is not None and self._planners.alive:
            # route requests are planned in the planning processes, which build the table; here
            # only the replans a new frame or a request asks for: no table (A* on the map)
            build = lambda: PlanningMap(snap.obstacles, robot_radius=radius, margin=margin, bounds=snap.bounds)  # noqa: E731
        else:
            build = lambda: prepared_map(snap.obstacles, radius, margin, snap.bounds)  # noqa: E731
        return self._maps.get((snap.frame, radius, margin), build)

    def _create_route(self, req: models.RouteRequest) -> models.Route:
        self._check_thread()
        snap = self.snapshot()
        radius = self._radius(req.robot_radius)
        route = self._plan(snap, (), req.start, req.goal, radius, req.margin)
        return self._add_route(req, snap, radius, route)

    def _add_route(self, req: models.RouteRequest, snap: Snapshot, radius: float, route: Any) -> models.Route:
        """Keep a route planned on ``snap`` (state thread). Planned in a planning process, it may
        come back after a newer frame was made current, whose check of the routes it missed:
        it is checked here against that frame (and replanned if a new obstacle blocks it)."""
        self._check_thread()
        old = self._state
        rid = f"r{next(self._route_ids)}"
        model = route_model(rid=rid, owner=req.owner, version=1, frame=snap.frame, reason="created", route=route,
                            start=req.start, goal=req.goal, position=req.start, robot_radius=radius,
                            margin=req.margin, extras=0, planner=self.planner)
        rec = RouteRecord(model=model, route=route, goal=(req.goal[0], req.goal[1]), position=(req.start[0], req.start[1]),
                          robot_radius=radius, margin=float(req.margin), extras=(), planned_on=snap.keys)
        current = old.snapshot
        later = None
        if current is not snap and current is not None:
            later = self._check_route(rec, current)
        routes = old.routes_copy()
        routes[rid] = rec if later is None else later
        while len(routes) > self.max_routes:
            del routes[next(iter(routes))]
        self._state = old.with_routes(routes)
        self._emit(models.RouteEvent, rec.owner, dict(route=model))
        if later is not None and later.model is not model:
            self._emit(models.RouteEvent, later.owner, dict(route=later.model))
            return later.model
        return model

    def _replan_route(self, rid: str, req: models.ReplanRequest) -> models.Route:
        self._check_thread()
        rec = self.route(rid)
        extras = rec.extras
        if req.obstacle is not None:
            extras = extras + (_polygon(req.obstacle),)
        new = self._replanned(rec, self.snapshot(), (req.position[0], req.position[1]), extras, reason="replan",
                              raise_errors=True)
        self._put(new)
        self._emit(models.RouteEvent, new.owner, dict(route=new.model))
        return new.model

    def _replanned(self, rec: RouteRecord, snap: Snapshot, position: tuple[float, float],
                   extras: tuple[Polygon, ...], *, reason: str, raise_errors: bool) -> RouteRecord:
        """A new version of ``rec``: a route from ``position`` to its goal around the snapshot's
        obstacles and ``extras``; with ``raise_errors=False`` a failure gives a blocked route."""
        m = rec.model
        error = route = None
        try:
            route = self._plan(snap, extras, position, rec.goal, rec.robot_radius, rec.margin)
        except SbplanError as exc:
            if raise_errors:
                raise
            _, code = status_and_code(exc)
            error = models.Error(code=code, message=str(exc))
        model = route_model(rid=m.id, owner=m.owner, version=m.version + 1, frame=snap.frame, reason=reason,
                            route=route, start=m.start_m, goal=rec.goal, position=position,
                            robot_radius=rec.robot_radius, margin=rec.margin, extras=len(extras),
                            planner=self.planner, error=error)
        return rec.evolve(model=model, route=route, position=position, extras=extras,
                          planned_on=snap.keys | frozenset(obstacle_key(p) for p in extras))

    def _put(self, rec: RouteRecord) -> None:
        old = self._state
        routes = old.routes_copy()
        routes.pop(rec.id, None)
        routes[rec.id] = rec
        self._state = old.with_routes(routes)

    def _delete_route(self, rid: str) -> None:
        self._check_thread()
        rec = self.route(rid)
        old = self._state
        routes = old.routes_copy()
        del routes[rid]
        self._state = old.with_routes(routes)
        self._emit(models.RouteDeletedEvent, rec.owner, dict(id=rid, owner=rec.owner))

    def _set_position(self, rid: str, position: tuple[float, float]) -> None:
        self._check_thread()
        rec = self.route(rid)
        old = self._state
        routes = old.routes_copy()
        routes[rid] = rec.evolve(position=tuple(position))
        self._state = old.with_routes(routes)

    # -- threads ----------------------------------------------------------------------------------
    def _state_submit(self, fn: Callable, *args: Any) -> concurrent.futures.Future:
        """Run a change on the state thread, as the writer."""
        return self._state_pool.submit(self._as_writer, fn, *args)

    def _as_writer(self, fn: Callable, *args: Any) -> Any:
        with self._write_lock:
            self._writer = threading.get_ident()
            try:
                return fn(*args)
            finally:
                self._writer = None

    def _check_thread(self) -> None:
        # every write holds the write lock: that is what makes read-modify-write safe
        assert threading.get_ident() == self._writer, "state changed without the write lock"

    def close(self) -> None:
        """Stop the worker threads (work already submitted finishes first)."""
        self._detect_pool.shutdown(wait=True)
        self._state_pool.shutdown(wait=True)
        if self._planners is not None:
            self._planners.close()


@dataclass(frozen=True)
class _Encoded:
    """A PNG or JPEG whose header was checked: its bytes and (width, height)."""

    data: bytes
    size: tuple[int, int]


def _polygon(points: list) -> Polygon:
    poly = Polygon(points)
    if not poly.is_valid or poly.area <= 0:
        raise InputError("obstacle: not a simple polygon with an area (edges cross, or the points are collinear)")
    return poly


def _parts(poly: Polygon) -> list[Polygon]:
    """A detected outline as valid polygons (a self-touching outline splits into its parts)."""
    if poly.is_valid:
        return [poly] if poly.area > 0 else []
    fixed = poly.buffer(0)
    return [p for p in getattr(fixed, "geoms", [fixed]) if isinstance(p, Polygon) and p.area > 0]


def _chain(src: concurrent.futures.Future, dst: concurrent.futures.Future) -> None:
    exc = src.exception()
    if exc is not None:
        dst.set_exception(exc)
    else:
        dst.set_result(src.result())
