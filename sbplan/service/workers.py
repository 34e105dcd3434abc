"""Planning processes: the service's route queries on every core.

Python threads run one at a time (the GIL), and a planning thread next to the event loop costs
more than the planning itself: the two threads hand the GIL back and forth at every numpy call
(on the service benchmark a 0.6 ms query took 1.3 ms of the state thread's CPU next to a busy
event loop). A :class:`PlannerPool` keeps one process per core, each with its own copy of the
planning maps, and answers ``POST /routes`` queries there; the service's state stays in the
service's process (the pool only plans, it keeps no state that matters: a map is rebuilt from
the obstacles it was sent).

Protocol (a :class:`multiprocessing.connection.Connection` per worker, pickled tuples):

- ``("frame", frame, obstacles, bounds)``: the obstacles (shapely polygons) of a frame, sent to
  a worker once, before its first query on that frame;
- ``("plan", job, frame, radius, margin, start, goal, planner, time_limit)``: a query; the answer
  is ``(job, True, (waypoints, status, planner, time_s))`` or ``(job, False, error)``.

The event loop sends and reads the pipes itself (``loop.add_reader``): no thread of its own.
"""

from __future__ import annotations

import asyncio
import itertools
import os
import pickle
import socket
import subprocess
import sys
from collections import OrderedDict
from multiprocessing.connection import Connection
from typing import Any

from ..errors import PluginError, SbplanError
from ..planning import PlanningMap, Route, plan

#: Frames a worker keeps the obstacles of, and planning maps it keeps (frame x robot size).
FRAMES_KEPT, MAPS_KEPT = 4, 8


class WorkerError(RuntimeError):
    """A planning process died or answered with an error that is not the user's (a bug)."""


def _serve(conn: Any) -> None:
    """A worker's loop: frames and queries in, answers out, until ``None`` or the pipe closes."""
    frames: OrderedDict[int, tuple] = OrderedDict()
    maps: OrderedDict[tuple, PlanningMap] = OrderedDict()
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        if msg[0] == "frame":
            _, frame, obstacles, bounds = msg
            frames[frame] = (obstacles, bounds)
            while len(frames) > FRAMES_KEPT:
                frames.popitem(last=False)
            continue
        _, job, frame, radius, margin, start, goal, planner, time_limit = msg
        try:
            key = (frame, radius, margin)
            pmap = maps.get(key)
            if pmap is None:
                obstacles, bounds = frames[frame]
                pmap = maps[key] = PlanningMap(obstacles, robot_radius=radius, margin=margin, bounds=bounds)
                pmap.prepare_routes()
                while len(maps) > MAPS_KEPT:
                    maps.popitem(last=False)
            else:
                maps.move_to_end(key)
            r = plan(pmap, start, goal, planner=planner, time_limit=time_limit)
            reply: tuple = (job, True, (r.waypoints, r.status, r.planner, r.time_s))
        except SbplanError as exc:
            reply = (job, False, _portable(exc))
        except Exception as exc:  # noqa: BLE001  (a bug: the service answers 500 and logs it)
            reply = (job, False, WorkerError(f"planning process: {type(exc).__name__}: {exc}"))
        conn.send(reply)


def _portable(exc: SbplanError) -> SbplanError:
    """The error itself when it survives pickling (the planning errors do), else a PluginError
    with its message (errors whose constructors take other arguments than the message)."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001
        return PluginError(str(exc))


class PlannerPool:
    """``processes`` planning processes, driven from one asyncio event loop.

    Each is a fresh Python running :func:`main`, a fresh interpreter talking over a socket
    pair: not forked (the service's process has threads), and not multiprocessing's spawn, which
    re-imports the caller's main module in the child.

    Parameters
    ----------
    processes : int
        How many; default one per core.
    """

    def __init__(self, processes: int | None = None):
        n = int(processes or os.cpu_count() or 1)
        if n < 1:
            raise ValueError(f"processes: must be >= 1, got {processes}")
        self._workers: list[_Worker] = []
        for _ in range(n):
            parent, child = socket.socketpair()
            with child:
                proc = subprocess.Popen([sys.executable, "-c", f"import {__name__} as w; w.main({child.fileno()})"],
                                        pass_fds=(child.fileno(),), stdin=subprocess.DEVNULL)
            self._workers.append(_Worker(proc, Connection(parent.detach())))
        self._jobs = itertools.count()
        self._loop: asyncio.AbstractEventLoop | None = None

    @property
    def alive(self) -> bool:
        return any(w.alive for w in self._workers)

    async def plan(self, frame: int, obstacles: Any, bounds: Any, *, radius: float, margin: float,
                   start: Any, goal: Any, planner: str, time_limit: float) -> Route:
        """The route from start to goal on the frame's obstacles (``obstacles``, ``bounds``: sent
        to a process the first time it plans on that frame). Raises what ``sbplan.plan``
        raises, or WorkerError."""
        loop = asyncio.get_running_loop()
        if self._loop is None:
            self._loop = loop
            for w in self._workers:
                if w.alive:
                    loop.add_reader(w.conn.fileno(), self._read, w)
        elif loop is not self._loop:
            raise RuntimeError("a PlannerPool is driven from one event loop")
        live = [w for w in self._workers if w.alive]
        if not live:
            raise WorkerError("no planning process is running")
        w = min(live, key=lambda w: len(w.pending))
        job = next(self._jobs)
        fut = loop.create_future()
        try:
            if frame not in w.frames:
                w.conn.send(("frame", frame, obstacles, bounds))
                w.frames[frame] = None
                while len(w.frames) > FRAMES_KEPT:
                    w.frames.popitem(last=False)
            w.conn.send(("plan", job, frame, radius, margin, tuple(start), tuple(goal), planner, time_limit))
        except OSError as exc:
            self._lost(w)
            raise WorkerError(f"planning process: {exc}") from None
        w.pending[job] = fut
        ok, payload = await fut
        if not ok:
            raise payload
        waypoints, status, name, time_s = payload
        return Route(waypoints, status=status, planner=name, time_s=time_s)

    def _read(self, w: "_Worker") -> None:
        try:
            job, ok, payload = w.conn.recv()
        except (EOFError, OSError):
            self._lost(w)
            return
        fut = w.pending.pop(job, None)
        if fut is not None and not fut.done():
            fut.set_result((ok, payload))

    def _lost(self, w: "_Worker") -> None:
        """A worker's pipe broke: its queries fail, the others go on."""
        if not w.alive:
            return
        w.alive = False
        if self._loop is not None:
            self._loop.remove_reader(w.conn.fileno())
        for fut in w.pending.values():
            if not fut.done():
                fut.set_result((False, WorkerError("a planning process stopped")))
        w.pending.clear()

    def close(self) -> None:
        """Stop the processes (call from the event loop's thread, or after it stopped)."""
        for w in self._workers:
            if w.alive and self._loop is not None and not self._loop.is_closed():
                self._loop.remove_reader(w.conn.fileno())
            w.alive = False
            try:
                w.conn.send(None)
            except OSError:
                pass
        for w in self._workers:
            try:
                w.proc.wait(5)
            except subprocess.TimeoutExpired:
                w.proc.kill()
                w.proc.wait()
            w.conn.close()


class _Worker:
    def __init__(self, proc: Any, conn: Any):
        self.proc, self.conn = proc, conn
        self.alive = True
        self.pending: dict[int, asyncio.Future] = {}
        self.frames: OrderedDict[int, None] = OrderedDict()  # frames whose obstacles it was sent


def main(fd: int) -> None:
    """A planning process (``PlannerPool`` starts it): serve the connection on ``fd``."""
    _serve(Connection(fd))
