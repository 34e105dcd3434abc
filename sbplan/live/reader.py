"""The reader thread: frames from a :class:`~sbplan.live.sources.Source` to the pipeline.

A live source (a camera, a URL, a file replayed in real time) runs at its own pace: the reader
keeps only the **latest** frame, so a pipeline step slower than the camera drops frames (counted)
instead of falling behind. A file or folder read as fast as the pipeline goes is read **every
frame**: the reader waits until the pipeline took the last one.

Faults. A read that fails (a stream lost) closes the source and opens it again with exponential
backoff, after the last frame delivered where the source can seek. A read that blocks cannot be
interrupted from another thread; :meth:`FrameReader.restart` leaves that thread behind (it exits
when its read returns, discarding what it read) and opens the source again in a new one.
"""

from __future__ import annotations

import collections
import threading
import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ..errors import SbplanError
from .sources import Capture, IterableSource, Source, SourceError


@dataclass(frozen=True, eq=False)
class Frame:
    """One frame handed to the pipeline.

    Attributes
    ----------
    image : ndarray (H, W) uint8
    number : int
        The source's frame number (live sources: frames read so far, from 0).
    time_ms : float
        The source's timestamp; for live sources the wall clock (milliseconds since the epoch)
        when the frame was read.
    captured : float
        ``time.perf_counter()`` when the read returned: latencies are measured from here.
    """

    image: np.ndarray
    number: int
    time_ms: float
    captured: float


@dataclass(frozen=True)
class Notice:
    """Something the reader tells the pipeline besides frames.

    ``kind``: ``"end"`` (no more frames), ``"lost"`` (a read failed; reopening), ``"opened"``
    (opened again after a fault or a restart; ``attempts`` opens it took), ``"gave-up"`` (could not
    be opened again within ``max_attempts``), ``"error"`` (the source cannot be used: ``error``).
    """

    kind: str
    attempts: int = 0
    error: str | None = None
    exception: BaseException | None = field(default=None, compare=False)


@dataclass
class ReaderStats:
    """Counters of the reader, all since it started."""

    read: int = 0  # frames decoded
    dropped: int = 0  # decoded but replaced by a newer frame before the pipeline took them
    corrupt: int = 0  # could not be decoded: skipped
    missing: int = 0  # gaps in the source's frame numbers (dropped before they reached us)
    lost: int = 0  # reads that failed (the source was opened again)
    opened: int = 0  # times the source was opened
    restarts: int = 0  # reader threads left behind in a blocked read


class FrameReader:
    """Reads ``source`` in a thread and hands over frames.

    Parameters
    ----------
    source : Source
    latest : bool, optional
        Keep only the latest frame (default: when the source is live).
    backoff : (float, float)
        First and largest wait in seconds between attempts to open the source again; each failed
        attempt doubles the wait.
    max_attempts : int or None
        Failed opens in a row after which the reader gives up (None: never, for cameras that
        come back).
    """

    def __init__(self, source: Source, *, latest: bool | None = None, backoff: tuple[float, float] = (0.5, 8.0),
                 max_attempts: int | None = None):
        self.source = source
        self.latest = source.live if latest is None else bool(latest)
        lo, hi = (float(v) for v in backoff)
        if not (0 <= lo <= hi):
            raise SbplanError(f"backoff: expected 0 <= first <= largest, got {backoff!r}")
        self.backoff = (lo, hi)
        self.max_attempts = max_attempts
        self.stats = ReaderStats()
        self._items: collections.deque[Frame | Notice] = collections.deque()
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._gen = 0
        self._last: int | None = None  # the last frame number handed to the queue
        self._thread: threading.Thread | None = None
        self._reading: int | None = None  # the generation inside a read, if any

    @property
    def reopenable(self) -> bool:
        """Can a blocked read be left behind and the source opened anew? (Not a Python iterable:
        it has one position that two threads cannot read.)"""
        return not isinstance(getattr(self.source, "inner", self.source), IterableSource)

    @property
    def blocked_reading(self) -> bool:
        """Is the current reader thread inside a read (not opening, not waiting to open)?"""
        return self._reading is not None and self._reading == self._gen

    def start(self) -> None:
        self._spawn(first=True)

    def _spawn(self, *, first: bool = False) -> None:
        with self._cond:
            gen = self._gen
            after = self._last
        t = threading.Thread(target=self._run, args=(gen, after, first), name=f"sbplan-reader-{gen}", daemon=True)
        self._thread = t
        t.start()

    def restart(self) -> bool:
        """Leave the current reader thread behind and open the source again in a new one.
        Returns False (and does nothing) for a source that cannot be reopened."""
        if not self.reopenable or self._stop.is_set():
            return False
        with self._cond:
            self._gen += 1
            self.stats.restarts += 1
        self._spawn()
        return True

    def stop(self) -> None:
        """Stop reading (the thread ends after its current read returns)."""
        self._stop.set()
        with self._cond:
            self._gen += 1
            self._cond.notify_all()

    def join(self, timeout: float) -> None:
        """Wait up to ``timeout`` seconds for the current reader thread to end (after :meth:`stop`);
        a thread blocked in a read is not waited for."""
        t = self._thread
        if t is not None and t is not threading.current_thread() and not self.blocked_reading:
            t.join(timeout)

    def get(self, timeout: float) -> Frame | Notice | None:
        """The next frame or notice, or None when none came within ``timeout`` seconds."""
        with self._cond:
            if not self._items:
                self._cond.wait(timeout)
            if not self._items:
                return None
            item = self._items.popleft()
            self._cond.notify_all()  # a reader waiting for room (every-frame mode)
            return item

    # -- the thread --------------------------------------------------------------------------------
    def _current(self, gen: int) -> bool:
        return gen == self._gen and not self._stop.is_set()

    def _put(self, gen: int, item: Frame | Notice) -> bool:
        with self._cond:
            if isinstance(item, Frame):
                if self.latest:
                    kept = [x for x in self._items if not isinstance(x, Frame)]
                    self.stats.dropped += len(self._items) - len(kept)
                    self._items = collections.deque(kept)
                else:
                    while any(isinstance(x, Frame) for x in self._items) and self._current(gen):
                        self._cond.wait(0.1)
            if not self._current(gen):
                return False
            self._items.append(item)
            if isinstance(item, Frame):
                self._last = item.number
            self._cond.notify_all()
            return True

    def _open(self, gen: int, after: int | None) -> Capture | None:
        """Open the source, retrying with backoff; None when stopped, left behind or given up."""
        delay, attempts = self.backoff[0], 0
        while self._current(gen):
            attempts += 1
            try:
                cap = self.source.open(after)
            except SourceError as exc:
                if self.max_attempts is not None and attempts >= self.max_attempts:
                    self._put(gen, Notice("gave-up", attempts, str(exc)))
                    return None
                self._stop.wait(delay)
                delay = min(max(delay * 2, 1e-3), self.backoff[1])
                continue
            except Exception as exc:  # noqa: BLE001  (a file gone or unreadable: the pipeline decides)
                self._put(gen, Notice("error", attempts, str(exc), exc))
                return None
            self.stats.opened += 1
            self._opened_attempts = attempts
            return cap
        return None

    def _run(self, gen: int, after: int | None, first: bool) -> None:
        reopened = not first
        while self._current(gen):
            cap = self._open(gen, after)
            if cap is None:
                return
            if reopened and not self._put(gen, Notice("opened", self._opened_attempts)):
                cap.close()
                return
            try:
                result = self._read_all(gen, cap, after)
            finally:
                cap.close()
            if result == "end":
                return
            after = result
            reopened = True
            # lost: wait the first backoff before opening again, so a dead camera is not hammered
            self._stop.wait(self.backoff[0])

    def _read_all(self, gen: int, cap: Capture, after: int | None) -> int | None | Literal["end"]:
        """Read until the end ("end"), a failure (returns the last frame number), or left behind."""
        src = self.source
        while True:
            self._reading = gen
            try:
                r = cap.read()
            finally:
                if self._reading == gen:
                    self._reading = None
            now = time.perf_counter()
            if not self._current(gen):
                return "end"
            self.stats.corrupt += r.corrupt
            if r.status == "frame":
                assert r.image is not None  # a "frame" read always carries its image
                self.stats.read += 1
                if src.live and r.number is None:
                    number = self.stats.read - 1
                    t = time.time() * 1000.0
                else:
                    number = r.number if r.number is not None else self.stats.read - 1
                    t = r.time_ms if r.time_ms is not None else time.time() * 1000.0
                    if after is not None and number > after + 1:
                        self.stats.missing += max(number - after - 1 - r.corrupt, 0)
                after = number
                if not self._put(gen, Frame(r.image, number, float(t), now)):
                    return "end"
            elif r.status == "corrupt":
                self.stats.corrupt += 1
                if r.number is not None:
                    if after is not None and r.number > after + 1:
                        self.stats.missing += r.number - after - 1
                    after = r.number
            elif r.status == "end":
                # released before the pipeline hears of it: a program that exits right after the
                # end must not kill this thread inside the decoder's teardown
                cap.close()
                self._put(gen, Notice("end"))
                return "end"
            else:  # lost
                self.stats.lost += 1
                self._put(gen, Notice("lost", error="the source stopped delivering frames"))
                return after
