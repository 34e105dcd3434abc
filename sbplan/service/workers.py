"""Planning processes: the service's route queries on every core.

Python threads run one at a time (the GIL), and a planning thread next to the event loop costs
more than the planning itself: the two threads hand the GIL back and forth at every numpy call
(on the service benchmark a 0.6 ms query took 1.3 ms of the state thread's CPU next to a busy
event loop). A :class:`PlannerPool` keeps one process per core, each with its own copy of the
planning maps, and answers ``POST /routes`` queries there; the service's state stays in the
service's process (the pool only plans, it keeps no state that matters: a map is rebuilt from
the obstacles it was sent).

Protocol (a socket pair per worker; pickled tuples, each framed by its length as 4 bytes,
big-endian):

- ``("frame", frame, obstacles, bounds)``: the obstacles (shapely polygons) of a frame, sent to
  a worker once, before its first query on that frame;
- ``("plan", job, frame, radius, margin, start, goal, planner, time_limit)``: a query; the answer
  is ``(job, True, (waypoints, status, planner, time_s))`` (the waypoints (M, 2) ``(x, y)`` as
  float64 bytes) or ``(job, False, error)``.

The event loop sends and reads the sockets itself (``loop.add_reader``): no thread of its own.
Both ends read whatever has arrived and take every whole message from it, and the event loop
sends the queries of one loop iteration to a worker in one write: with 32 clients the queries
and answers come in bursts, and a read or write per message (multiprocessing's Connection reads
each message's length and body separately) cost more of the two cores than the pickling.
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
from typing import Any

import numpy as np

from ..errors import PluginError, SbplanError
from ..planning import PlanningMap, Route, plan
from ..planning.plan_replan import MapCache

#: Frames a worker keeps the obstacles of, and planning maps it (and the service's state thread)
#: keeps, one per frame and robot size: routes of a few robot sizes on the current frame, and the
#: previous frame's while its routes are checked.
FRAMES_KEPT, MAPS_KEPT = 4, 8


class WorkerError(RuntimeError):
    """A planning process died or answered with an error that is not the user's (a bug)."""


def _frame(obj: Any) -> bytes:
    """``obj`` pickled, after its length (4 bytes, big-endian)."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    return len(data).to_bytes(4, "big") + data


def _unframe(buf: bytearray) -> list:
    """The whole messages at the start of ``buf``, removed from it (a partial one stays)."""
    out, at = [], 0
    while len(buf) - at >= 4:
        n = int.from_bytes(buf[at:at + 4], "big")
        if len(buf) - at - 4 < n:
            break
        out.append(pickle.loads(buf[at + 4:at + 4 + n]))
        at += 4 + n
    del buf[:at]
    return out


def _messages(sock: socket.socket):
    """The messages arriving on ``sock`` (blocking), until it closes."""
    buf = bytearray()
    while True:
        try:
            data = sock.recv(1 << 16)
        except OSError:
            return
        if not data:
            return
        buf += data
        yield from _unframe(buf)


def prepared_map(obstacles: Any, radius: float, margin: float, bounds: Any) -> PlanningMap:
    """A frame's planning map for a robot size, with its corner-to-corner table: the service asks
    many routes of one map, so the table is built once (tens of ms on a 50-obstacle floor) and a
    query then costs the visibility of its two ends."""
    pmap = PlanningMap(obstacles, robot_radius=radius, margin=margin, bounds=bounds)
    pmap.prepare_routes()
    return pmap


def _serve(sock: socket.socket) -> None:
    """A worker's loop: frames and queries in, answers out, until ``None`` or the socket closes."""
    frames: OrderedDict[int, tuple] = OrderedDict()
    maps = MapCache(MAPS_KEPT)
    for msg in _messages(sock):
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
            obstacles, bounds = frames[frame]
            pmap = maps.get((frame, radius, margin), lambda: prepared_map(obstacles, radius, margin, bounds))
            r = plan(pmap, start, goal, planner=planner, time_limit=time_limit)
            # the waypoints as raw float64 bytes: pickling the array costs ~25 us a reply
            wp = np.ascontiguousarray(r.waypoints, dtype=np.float64).tobytes()
            reply: tuple = (job, True, (wp, r.status, r.planner, r.time_s))
        except SbplanError as exc:
            reply = (job, False, _portable(exc))
        except Exception as exc:  # noqa: BLE001  (a bug: the service answers 500 and logs it)
            reply = (job, False, WorkerError(f"planning process: {type(exc).__name__}: {exc}"))
        try:
            sock.sendall(_frame(reply))
        except OSError:
            return


def _portable(exc: SbplanError) -> SbplanError:
    """The error itself when it survives pickling (the planning errors do), else a PluginError
    with its message (errors whose constructors take other arguments than the message)."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001
        return PluginError(str(exc))


def default_processes() -> int:
    """Planning processes for this machine: one per core but one, at least one. The event loop
    that reads and answers the requests needs a core of its own: on 2 cores, 32 closed-loop
    clients got p99 24.6-31.9 ms with one planning process and 33.0-37.7 ms with two (alternating
    runs of ``sbplan bench serve``)."""
    return max(1, (os.cpu_count() or 1) - 1)


class PlannerPool:
    """``processes`` planning processes, driven from one asyncio event loop.

    Each is a fresh Python running :func:`main`, a fresh interpreter talking over a socket
    pair: not forked (the service's process has threads), and not multiprocessing's spawn, which
    re-imports the caller's main module in the child.

    Parameters
    ----------
    processes : int
        How many; default :func:`default_processes`.
    """

    def __init__(self, processes: int | None = None):
        n = int(processes or default_processes())
        if n < 1:
            raise ValueError(f"processes: must be >= 1, got {processes}")
        self._workers: list[_Worker] = []
        for _ in range(n):
            parent, child = socket.socketpair()
            with child:
                proc = subprocess.Popen([sys.executable, "-c", f"import {__name__} as w; w.main({child.fileno()})"],
                                        pass_fds=(child.fileno(),), stdin=subprocess.DEVNULL)
            self._workers.append(_Worker(proc, parent))
        self._jobs = itertools.count()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._flush_due = False

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
                    loop.add_reader(w.sock.fileno(), self._read, w)
        elif loop is not self._loop:
            raise RuntimeError("a PlannerPool is driven from one event loop")
        live = [w for w in self._workers if w.alive]
        if not live:
            raise WorkerError("no planning process is running")
        w = min(live, key=lambda w: len(w.pending))
        job = next(self._jobs)
        fut = loop.create_future()
        if frame not in w.frames:
            w.out += _frame(("frame", frame, obstacles, bounds))
            w.frames[frame] = None
            while len(w.frames) > FRAMES_KEPT:
                w.frames.popitem(last=False)
        w.out += _frame(("plan", job, frame, radius, margin, tuple(start), tuple(goal), planner, time_limit))
        w.pending[job] = fut
        if not self._flush_due:  # sent after this loop iteration's other requests: one write
            self._flush_due = True
            loop.call_soon(self._flush)
        ok, payload = await fut
        if not ok:
            raise payload
        waypoints, status, name, time_s = payload
        return Route(np.frombuffer(waypoints, dtype=np.float64).reshape(-1, 2), status=status, planner=name,
                     time_s=time_s)

    def _flush(self) -> None:
        self._flush_due = False
        for w in self._workers:
            if w.out and w.alive:
                data, w.out = bytes(w.out), bytearray()
                try:
                    # blocking: a worker reads as it plans, so only a backlog of megabytes waits
                    w.sock.sendall(data)
                except OSError:
                    self._lost(w)

    def _read(self, w: "_Worker") -> None:
        try:
            data = w.sock.recv(1 << 16)
        except OSError:
            data = b""
        if not data:
            self._lost(w)
            return
        w.buf += data
        for job, ok, payload in _unframe(w.buf):
            fut = w.pending.pop(job, None)
            if fut is not None and not fut.done():
                fut.set_result((ok, payload))

    def _lost(self, w: "_Worker") -> None:
        """A worker's pipe broke: its queries fail, the others go on."""
        if not w.alive:
            return
        w.alive = False
        w.out = bytearray()
        if self._loop is not None:
            self._loop.remove_reader(w.sock.fileno())
        for fut in w.pending.values():
            if not fut.done():
                fut.set_result((False, WorkerError("a planning process stopped")))
        w.pending.clear()

    def close(self) -> None:
        """Stop the processes (call from the event loop's thread, or after it stopped)."""
        for w in self._workers:
            if w.alive and self._loop is not None and not self._loop.is_closed():
                self._loop.remove_reader(w.sock.fileno())
            w.alive = False
            try:
                w.sock.sendall(bytes(w.out) + _frame(None))
            except OSError:
                pass
        for w in self._workers:
            try:
                w.proc.wait(5)
            except subprocess.TimeoutExpired:
                w.proc.kill()
                w.proc.wait()
            w.sock.close()


class _Worker:
    def __init__(self, proc: Any, sock: socket.socket):
        self.proc, self.sock = proc, sock
        self.out = bytearray()  # messages not sent yet (see PlannerPool._flush)
        self.buf = bytearray()  # bytes read, not a whole message yet
        self.alive = True
        self.pending: dict[int, asyncio.Future] = {}
        self.frames: OrderedDict[int, None] = OrderedDict()  # frames whose obstacles it was sent


def main(fd: int) -> None:
    """A planning process (``PlannerPool`` starts it): serve the socket on ``fd``."""
    from .server import freeze_startup_objects

    freeze_startup_objects()
    _serve(socket.socket(fileno=fd))
