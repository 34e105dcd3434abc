"""Watching a stream: every frame through one detector, a stable state, events, the route.

:class:`Watcher` is the live pipeline. :meth:`Watcher.events` runs it in the calling thread and
yields events (plain dicts, the JSON lines of ``sbplan watch``; their schema is
``sbplan/live/schemas/events.schema.json``); :meth:`Watcher.run` calls a function for each;
:attr:`Watcher.state` is the current :class:`LiveState`, readable from any thread at any time.
"""

from __future__ import annotations

import collections
import math
import os
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterator, TypedDict

import cv2
import numpy as np

from ..detection import Detector
from ..detection.calibration import Calibration, load_calibration
from ..detection.obstacles import DEFAULT_OBSTACLE_MODEL, check_obstacle_model
from ..detection.registration import apply
from ..imageio import as_gray
from ..errors import CameraMotionError, DetectionError, InputError, PlanningError, SbplanError
from ..planning import plan, replan
from .reader import Frame, FrameReader, Notice
from .sources import Source, open_source
from .tracking import CellHysteresis, Change, Hysteresis, ObstacleTracker, reusable_obstacles

if TYPE_CHECKING:
    from ..detection.obstacles import Obstacle
    from ..detection.registration import CameraMotion
    from ..planning import Route

#: One event: a JSON object of ``sbplan/live/schemas/events.schema.json`` (its keys depend on its
#: ``type``, so a plain dict).
Event = dict[str, Any]

#: Why a watch stopped -> the exit code of ``sbplan watch``.
EXIT_CODES = {
    "ended": 0,  # the file or folder had no more frames
    "limit": 0,  # --max-frames frames were processed
    "stopped": 0,  # Watcher.stop() (the TUI, a program)
    "error": 1,  # the frames cannot be used with this calibration (size), or the source failed
    "source-lost": 3,  # the source could not be opened again within --max-reopen attempts
    "interrupted": 130,  # Ctrl-C (SIGINT)
    "terminated": 143,  # SIGTERM
}
#: The thumbnail compared to tell an unchanged frame takes one 2 x 2-pixel mean per THUMB_BLOCK x
#: THUMB_BLOCK pixels (a bilinear quarter-size resize: a sixth of the cost of whole-block means,
#: and anything hiding part of a symbol covers many such samples).
THUMB_BLOCK = 4
#: A frame's changed part is located to CHANGE_POOL x CHANGE_POOL thumbnail samples (16 pixels):
#: finer costs more than it saves (the detector re-examines whole cells around it anyway).
CHANGE_POOL = 4
#: Latencies kept for the median and 99th percentile.
LATENCY_WINDOW = 10000
#: How often the pipeline wakes up to look for a stall when no frame comes, seconds.
POLL_S = 0.05


@dataclass(frozen=True, eq=False)
class LiveState:
    """The state of a watch at one moment.

    Attributes
    ----------
    frame : int or None
        The number of the last frame processed.
    time_ms : float or None
        Its timestamp (the source's; the wall clock for live sources), milliseconds.
    occupied : ndarray (rows, cols) bool
        The stable occupied cells (after hysteresis); ``[row, col]``, row 0 at the top.
    seen : ndarray (rows, cols) bool or None
        What the last registered frame alone showed.
    obstacles : tuple of Obstacle
        The stable obstacles, with lasting ids (:class:`~sbplan.detection.obstacles.Obstacle`).
    camera : CameraMotion or None
        The camera's movement since calibration, as the last registered frame showed it.
    camera_error : str or None
        Set while frames cannot be registered (the camera moved too far: recalibrate).
    route : Route or None
        The current route (with ``start``/``goal``); ``route_error`` says why there is none.
    image : ndarray (H, W) uint8 or None
        The last frame processed (kept only with ``keep_image``).

    The counters (frames per second, drops, latency) are :meth:`Watcher.stats`.
    """

    frame: int | None
    time_ms: float | None
    occupied: np.ndarray
    seen: np.ndarray | None = None
    obstacles: tuple[Obstacle, ...] = ()
    camera: CameraMotion | None = None
    camera_error: str | None = None
    route: Route | None = None
    route_error: str | None = None
    image: np.ndarray | None = None


class Latency(TypedDict):
    """Milliseconds from a frame's capture to the end of its processing."""

    median: float
    p99: float


class WatchStats(TypedDict):
    """What :meth:`Watcher.stats` counts (the ``stats`` of ``stats`` and ``ended`` events)."""

    frames_read: int
    frames_processed: int
    frames_unchanged: int
    frames_local: int
    frames_dropped: int
    frames_corrupt: int
    frames_missing: int
    frames_unregistered: int
    reconnects: int
    fps: float | None
    fps_mean: float | None
    latency_ms: Latency | None
    cpu_ms_per_frame: float | None


def _point(value: Any, name: str) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a point (x, y) in metres, got {value!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"{name}: expected a finite point (x, y), got {value!r}")
    return x, y


class Watcher:
    """The live pipeline on one stream.

    Parameters
    ----------
    source : str, int, path, Source or iterable
        What :func:`~sbplan.live.sources.open_source` opens: a video file, a folder of images,
        a camera index, a URL, or Python frames.
    calibration : Calibration or path
    hysteresis : Hysteresis or str
        How long a cell must be seen changed (``"3"`` frames, ``"0.3s"``).
    stall_timeout : float
        Seconds without a frame after which the source is reported stalled (and, when it is
        blocked in a read, opened again).
    backoff : (float, float)
        First and largest wait between attempts to open a failed source, seconds.
    max_reopen : int or None
        Failed opens in a row after which the watch ends with ``source-lost`` (None: never).
    latest : bool, optional
        Keep only the latest frame (default: for live sources; files are read every frame).
    start, goal : (x, y) metres, optional
        Keep a route from start to goal, planned again whenever the obstacles change.
    robot_radius : float, optional
        Default: the calibration's workspace's.
    skip_unchanged : bool
        Reuse the last frame's cells when a frame's thumbnail (a 2 x 2-pixel mean every 4 pixels)
        differs from the last detected frame's by at most ``change_threshold`` grey levels
        everywhere (a still floor costs a thumbnail, not a detection).
    local : bool
        With ``skip_unchanged``: when a frame's thumbnail changed in part of the frame only, look
        again only at the cells near the change, keeping the others' and the camera's pose
        (:meth:`~sbplan.detection.Detector.find_cells_local`); a camera bump or a change over
        much of the frame is detected whole, registration included.
    camera_tolerance_px : float
        A camera movement is reported when it moves some image corner by more than this since
        the last report.
    max_frames : int, optional
        Stop after this many frames processed (reason ``limit``).
    stats_interval : float, optional
        Seconds between ``stats`` events (None: none).
    obstacle_model : "mar" | "parts" | "outline", optional
        What the route is planned around (default ``parts``, :mod:`sbplan.detection.obstacles`).
    keep_image : bool
        Keep the last frame in :attr:`state` (for a display).
    **stages
        Detector stage overrides (``binarizer=``, ``matcher=`` ...).
    """

    def __init__(self, source: Any, calibration: Calibration | str | os.PathLike[str], *, hysteresis: Hysteresis | str = Hysteresis(),
                 stall_timeout: float = 5.0, backoff: tuple[float, float] = (0.5, 8.0), max_reopen: int | None = None,
                 latest: bool | None = None, start: Any = None, goal: Any = None, robot_radius: float | None = None,
                 skip_unchanged: bool = True, local: bool = True, change_threshold: float = 10.0, camera_tolerance_px: float = 1.0,
                 max_frames: int | None = None, stats_interval: float | None = None, keep_image: bool = False,
                 fps: float | None = None, obstacle_model: str | None = None, **stages: Any):
        if not isinstance(hysteresis, Hysteresis):
            hysteresis = Hysteresis.parse(hysteresis)
        for name, v, low in (("stall_timeout", stall_timeout, 0.0), ("change_threshold", change_threshold, 0.0),
                             ("camera_tolerance_px", camera_tolerance_px, 0.0)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= low:
                raise InputError(f"{name}: expected a number > {low:g}, got {v!r}")
        if max_frames is not None and (not isinstance(max_frames, int) or max_frames < 1):
            raise InputError(f"max_frames: expected an integer >= 1, got {max_frames!r}")
        if max_reopen is not None and (not isinstance(max_reopen, int) or max_reopen < 1):
            raise InputError(f"max_reopen: expected an integer >= 1, got {max_reopen!r}")
        if stats_interval is not None and not (isinstance(stats_interval, (int, float)) and stats_interval > 0):
            raise InputError(f"stats_interval: expected a number of seconds > 0, got {stats_interval!r}")

        self.obstacle_model = check_obstacle_model(obstacle_model or DEFAULT_OBSTACLE_MODEL)
        self.calibration = cal = calibration if isinstance(calibration, Calibration) else load_calibration(calibration)
        self.start, self.goal = _point(start, "start"), _point(goal, "goal")
        if (self.start is None) != (self.goal is None):
            raise InputError("start/goal: give both, or neither")
        self.robot_radius = float(cal.workspace.robot_radius_m if robot_radius is None else robot_radius)
        if not (math.isfinite(self.robot_radius) and self.robot_radius >= 0):
            raise InputError(f"robot_radius: expected a number >= 0, got {robot_radius!r}")
        self.bounds = cal.world_bounds()
        for name, p in (("start", self.start), ("goal", self.goal)):
            if p is not None and not (self.bounds[0] <= p[0] <= self.bounds[2] and self.bounds[1] <= p[1] <= self.bounds[3]):
                raise InputError(f"{name}: ({p[0]:g}, {p[1]:g}) lies outside the floor {self.bounds} (metres)")
        self.source: Source = open_source(source, fps=fps, timeout=stall_timeout)
        self.detector = Detector(cal, **stages)
        self.hysteresis = hysteresis
        self.stall_timeout = float(stall_timeout)
        self.backoff = backoff
        self.reader = FrameReader(self.source, latest=latest, backoff=backoff, max_attempts=max_reopen)
        self.skip_unchanged = bool(skip_unchanged)
        self.local = bool(local)
        self.change_threshold = float(change_threshold)
        self.camera_tolerance_px = float(camera_tolerance_px)
        self.max_frames = max_frames
        self.stats_interval = stats_interval
        self.keep_image = keep_image
        shape = cal.grid.shape
        self.cells = CellHysteresis(shape, hysteresis)
        pitch = float(np.mean(cal.grid.pitch_px))
        self.tracker = ObstacleTracker(reach_px=1.5 * pitch)
        # the camera pose each stable obstacle was outlined under, by its cells
        self._outline_poses: dict[tuple, np.ndarray] = {}
        self._state = LiveState(None, None, np.zeros(shape, bool))
        self._stop_reason: str | None = None
        self._running = threading.Event()
        self._running.set()
        self._replan = threading.Event()
        self._seq = 0
        self.reason: str | None = None
        self.error: str | None = None
        # per-frame bookkeeping
        self._thumb: np.ndarray | None = None
        self._last_raw: tuple[np.ndarray, CameraMotion] | None = None
        self._reported_pose: np.ndarray = np.eye(3)
        self._camera_lost = False
        self._route: Route | None = None
        self._route_error: str | None = None
        self._processed = self._skipped = self._unregistered = self._local = 0
        self._latencies: collections.deque[float] = collections.deque(maxlen=LATENCY_WINDOW)
        self._cpu_s = 0.0
        self._first_t: float | None = None
        self._last_t: float | None = None
        self._recent: collections.deque[float] = collections.deque(maxlen=64)

    # -- control, from any thread ------------------------------------------------------------------
    @property
    def state(self) -> LiveState:
        return self._state

    def stop(self, reason: str = "stopped") -> None:
        """Ask the pipeline to stop; :meth:`events` ends with an ``ended`` event of this reason."""
        if reason not in EXIT_CODES:
            raise InputError(f"reason: expected one of {', '.join(EXIT_CODES)}, got {reason!r}")
        if self._stop_reason is None:
            self._stop_reason = reason
        self.reader.stop()
        self._running.set()

    def pause(self) -> None:
        """Stop taking frames until :meth:`resume`: a live source's frames are dropped meanwhile
        (the reader keeps the latest), a file waits; no stall is reported while paused."""
        self._running.clear()

    def resume(self) -> None:
        self._running.set()

    @property
    def paused(self) -> bool:
        return not self._running.is_set()

    def replan(self, start: Any = None, goal: Any = None) -> None:
        """Plan the route anew on the next frame (with a new start and goal when given)."""
        s, g = _point(start, "start"), _point(goal, "goal")
        if s is not None:
            self.start = s
        if g is not None:
            self.goal = g
        self._replan.set()

    @property
    def exit_code(self) -> int:
        return EXIT_CODES.get(self.reason or "stopped", 1)

    def stats(self) -> WatchStats:
        """Counters since the start: frames read, processed, skipped as unchanged, detected in part
        only (``frames_local``), dropped by the
        reader, corrupt, missing from the source's numbering, unregistered; reconnects; frames per
        second; median and 99th-percentile latency (ms) from capture to the end of the frame's
        processing; CPU milliseconds per processed frame."""
        r = self.reader.stats
        lat = np.asarray(self._latencies) if self._latencies else None
        span = (self._last_t - self._first_t) if self._first_t is not None and self._last_t is not None else 0.0
        recent = list(self._recent)
        fps = (len(recent) - 1) / (recent[-1] - recent[0]) if len(recent) >= 2 and recent[-1] > recent[0] else None
        return {
            "frames_read": r.read, "frames_processed": self._processed, "frames_unchanged": self._skipped,
            "frames_local": self._local,
            "frames_dropped": r.dropped, "frames_corrupt": r.corrupt, "frames_missing": r.missing,
            "frames_unregistered": self._unregistered, "reconnects": r.opened - 1 if r.opened else 0,
            "fps": None if fps is None else round(fps, 3),
            "fps_mean": round((self._processed - 1) / span, 3) if span > 0 else None,
            "latency_ms": None if lat is None else {"median": round(float(np.median(lat)), 3),
                                                    "p99": round(float(np.percentile(lat, 99)), 3)},
            "cpu_ms_per_frame": round(self._cpu_s * 1e3 / self._processed, 3) if self._processed else None,
        }

    # -- the loop ----------------------------------------------------------------------------------
    def run(self, on_event: Callable[[Event], Any]) -> int:
        """Call ``on_event(event)`` for every event until the watch ends; return its exit code."""
        for event in self.events():
            on_event(event)
        return self.exit_code

    def events(self) -> Iterator[Event]:
        """Run the pipeline, yielding events as they happen; the last is ``ended``. A watcher runs
        once: make another to watch again."""
        if self._seq:
            raise InputError("events: this watcher has run already; make a new Watcher to watch again")
        reader = self.reader
        reason = None
        yield self._event("started", source={"name": self.source.name, "kind": self.source.kind,
                                             "live": bool(self.source.live), "latest": reader.latest},
                          calibration={"rows": self.calibration.grid.rows, "cols": self.calibration.grid.cols,
                                       "width": int(self.calibration.image_shape[1]),
                                       "height": int(self.calibration.image_shape[0])},
                          hysteresis=self.hysteresis.to_json(), stall_timeout_s=self.stall_timeout,
                          start=None if self.start is None else list(self.start),
                          goal=None if self.goal is None else list(self.goal), robot_radius=self.robot_radius)
        reader.start()
        last_frame_at = time.perf_counter()
        down_since: float | None = None
        stalled, reopened, attempts = False, False, 0
        restart_at, restart_delay = None, self.stall_timeout
        interval = self.stats_interval
        next_stats = time.perf_counter() + interval if interval else None
        try:
            while True:
                if self._stop_reason is not None:
                    reason = self._stop_reason
                    break
                if not self._running.is_set():
                    self._running.wait(POLL_S)
                    last_frame_at = time.perf_counter()  # a pause is not a stall
                    continue
                item = reader.get(POLL_S)
                now = time.perf_counter()
                if next_stats is not None and interval and now >= next_stats:
                    next_stats = now + interval
                    yield self._event("stats", stats=self.stats())
                if item is None:
                    if not stalled and now - last_frame_at >= self.stall_timeout:
                        stalled = True
                        down_since = down_since if down_since is not None else last_frame_at
                        yield self._event("stalled", since_last_frame_s=round(now - last_frame_at, 3),
                                          timeout_s=self.stall_timeout,
                                          reason="reopening after a failed read" if reopened else "no frame")
                        restart_at = now
                    if stalled and restart_at is not None and now >= restart_at and reader.blocked_reading:
                        if reader.restart():
                            reopened = True
                        restart_at = now + restart_delay
                        restart_delay = min(2 * restart_delay, max(self.backoff[1], self.stall_timeout))
                    continue
                if isinstance(item, Notice):
                    if item.kind == "end":
                        reason = "ended"
                        break
                    if item.kind == "gave-up":
                        reason, self.error = "source-lost", item.error
                        break
                    if item.kind == "error":
                        reason, self.error = "error", item.error
                        break
                    if item.kind == "lost":
                        down_since = down_since if down_since is not None else now
                        reopened = True
                    elif item.kind == "opened":
                        reopened, attempts = True, attempts + item.attempts
                    continue
                if down_since is not None:
                    yield self._event("reconnected", item, down_s=round(now - down_since, 3), reopened=reopened,
                                      attempts=attempts)
                down_since, stalled, reopened, attempts = None, False, False, 0
                restart_at, restart_delay = None, self.stall_timeout
                last_frame_at = now
                yield from self._process(item)
                if self.reason == "error":
                    reason = "error"
                    break
                if self.max_frames is not None and self._processed >= self.max_frames:
                    reason = "limit"
                    break
        except KeyboardInterrupt:
            reason = "interrupted"
        finally:
            reader.stop()
            reader.join(1.0)
        self.reason = reason
        yield self._event("ended", reason=reason, exit_code=self.exit_code, error=self.error, stats=self.stats())

    # -- one frame ---------------------------------------------------------------------------------
    def _process(self, frame: Frame) -> Iterator[Event]:
        cpu0 = time.thread_time()
        image = frame.image
        cal = self.calibration
        events: list[Event] = []
        reused = None  # the last frame's cells and camera, when this frame did not change
        thumb = changed = None
        if self.skip_unchanged and self._last_raw is not None and not self._replan.is_set():
            h, w = image.shape[:2]
            thumb = cv2.resize(image, (w // THUMB_BLOCK, h // THUMB_BLOCK), interpolation=cv2.INTER_LINEAR)
            if self._thumb is not None and thumb.shape == self._thumb.shape:
                diff = cv2.absdiff(thumb, self._thumb)
                if float(diff.max()) <= self.change_threshold:
                    reused = self._last_raw
                elif self.local:
                    diff = diff.max(axis=2) if diff.ndim == 3 else diff
                    # (0/255, as changed_boxes wants it)
                    changed = np.where(diff > self.change_threshold, np.uint8(255), np.uint8(0))
        found = None
        if changed is not None and thumb is not None:
            found = self.detector.find_cells_local(image, changed_boxes(changed, THUMB_BLOCK))
        if reused is not None:
            self._skipped += 1
            raw, motion = reused
        elif found is not None and thumb is not None and self._thumb is not None:
            self._local += 1
            raw, motion = found.occupied, found.camera
            self._last_raw = (raw, motion)
            self._thumb = refreshed(self._thumb, thumb, self.detector.kept_reads(), THUMB_BLOCK)
        else:
            try:
                found = self.detector.find_cells(image)
            except CameraMotionError as exc:
                self._unregistered += 1
                if not self._camera_lost:
                    self._camera_lost = True
                    events.append(self._event("camera_moved", frame, camera=None, registered=False, error=str(exc)))
                self._finish(frame, cpu0, events, camera_error=str(exc))
                yield from events
                return
            except DetectionError as exc:
                # not a bad frame but frames this calibration cannot read (their size): no use going on
                self.reason, self.error = "error", str(exc)
                self._cpu_s += time.thread_time() - cpu0
                return
            raw, motion = found.occupied, found.camera
            self._last_raw = (raw, motion)
            if self.skip_unchanged:
                h, w = image.shape[:2]
                self._thumb = thumb if thumb is not None else cv2.resize(
                    image, (w // THUMB_BLOCK, h // THUMB_BLOCK), interpolation=cv2.INTER_LINEAR)
        # the camera: report a movement beyond the tolerance, and registration coming back (a
        # reused frame has the last frame's pose, which was reported or within the tolerance)
        moved_px = 0.0 if reused is not None and not self._camera_lost else self._pose_change(motion.matrix)
        if self._camera_lost or moved_px > self.camera_tolerance_px:
            self._camera_lost = False
            self._reported_pose = motion.matrix
            events.append(self._event("camera_moved", frame, camera=motion.to_json(), registered=True, error=None,
                                      moved_px=round(moved_px, 3)))
        flipped = self.cells.update(raw, frame.time_ms)
        changes: list[Change] = []
        if flipped.any():
            found_obs = self._obstacles(image, motion)
            _, changes = self.tracker.update(found_obs)
            for ch in changes:
                fields: dict[str, Any] = {"obstacle": ch.obstacle.to_json()}
                if ch.kind == "moved" and ch.previous is not None:  # a move always has its previous state
                    before, after = set(map(tuple, ch.previous.cells)), set(map(tuple, ch.obstacle.cells))
                    fields.update(previous=ch.previous.to_json(), cells_added=[list(c) for c in sorted(after - before)],
                                  cells_removed=[list(c) for c in sorted(before - after)])
                events.append(self._event(f"obstacle_{ch.kind}", frame, **fields))
        if self.start is not None and (changes or self._replan.is_set() or (self._route is None and self._route_error is None)):
            forced = self._replan.is_set()
            self._replan.clear()
            event = self._plan(frame, changes, forced)
            if event is not None:
                events.append(event)
        self._finish(frame, cpu0, events, raw=raw, motion=motion)
        yield from events

    def _obstacles(self, image: np.ndarray, motion: CameraMotion) -> list[Obstacle]:
        """The obstacles of the stable cells, after a flip: each one's outline by the detector's
        footprint stage on this frame, except those whose group of cells did not change since they
        were outlined under (within ``camera_tolerance_px``) the same camera pose, which are kept
        as they were (:func:`~sbplan.live.tracking.reusable_obstacles`): a flip in one corner of
        the floor costs the footprints of that corner only."""
        cal = self.calibration
        stable = self.cells.stable
        poses = self._outline_poses

        def same_pose(ob: Obstacle) -> bool:
            pose = poses.get(tuple(ob.cells))
            return pose is not None and self._corner_shift(pose, motion.matrix) <= self.camera_tolerance_px

        kept, todo = reusable_obstacles(stable, self.tracker.obstacles, keep=same_pose)
        found = list(kept)
        if todo.any():
            occupancy = self.detector.mapper.occupancy_image(cal.grid, todo, tuple(cal.image_shape))
            fresh = self.detector.obstacles(as_gray(image), todo, occupancy, motion)
            found += fresh
        else:
            fresh = []
        self._outline_poses = {**{tuple(o.cells): poses[tuple(o.cells)] for o in kept},
                               **{tuple(o.cells): motion.matrix for o in fresh}}
        # in reading order of their top-left cells, as the detector numbers them (the tracker's ties)
        far = (1 << 30, 1 << 30)
        found.sort(key=lambda o: tuple(o.cells[0]) if o.cells else far)
        return found

    def _corner_shift(self, a: np.ndarray, b: np.ndarray) -> float:
        """How far apart the poses ``a`` and ``b`` put the image's corners, pixels."""
        h, w = self.calibration.image_shape
        corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
        return float(np.abs(apply(a, corners) - apply(b, corners)).max())

    def _pose_change(self, matrix: np.ndarray) -> float:
        """How far ``matrix`` moves the image's corners from where the last reported pose put them."""
        return self._corner_shift(matrix, self._reported_pose)

    def _finish(self, frame: Frame, cpu0: float, events: list[Event], *, raw: np.ndarray | None = None,
                motion: CameraMotion | None = None, camera_error: str | None = None) -> None:
        now = time.perf_counter()
        self._processed += 1
        self._cpu_s += time.thread_time() - cpu0
        self._latencies.append((now - frame.captured) * 1e3)
        self._first_t = now if self._first_t is None else self._first_t
        self._last_t = now
        self._recent.append(now)
        old = self._state
        self._state = LiveState(
            frame.number, frame.time_ms, self.cells.stable.copy(), raw if raw is not None else old.seen,
            tuple(self.tracker.obstacles), motion if motion is not None else old.camera, camera_error,
            self._route, self._route_error, frame.image if self.keep_image else None)
        # the latency an event reports runs to when it is handed out
        t = time.perf_counter()
        for e in events:
            if e.get("frame") == frame.number and e.get("latency_ms") is not None:
                e["latency_ms"] = round((t - frame.captured) * 1e3, 3)

    # -- the route ---------------------------------------------------------------------------------
    def _plan(self, frame: Frame, changes: list[Change], forced: bool) -> Event | None:
        """Plan or replan after ``changes``; the route event, or None when the route stays."""
        model = self.obstacle_model
        obstacles = [p for o in self.tracker.obstacles for p in o.polygons_m(model)]
        appeared_only = changes and all(c.kind == "appeared" for c in changes)
        # only new obstacles: the route is updated from its map, not planned anew
        base = self._route if appeared_only and not forced else None
        incremental = base is not None
        t0 = time.perf_counter()
        try:
            if base is not None:
                new = [p for c in changes for p in c.obstacle.polygons_m(model)]
                route = replan(base, self.start, new)
            else:
                route = plan(obstacles, self.start, self.goal, robot_radius=self.robot_radius, bounds=self.bounds)
        except PlanningError as exc:
            had = self._route is not None or self._route_error != exc.reason
            self._route, self._route_error = None, exc.reason
            if not had and not forced:
                return None
            return self._event("route", frame, route=None, status="none", reason=exc.reason, error=str(exc),
                               incremental=incremental, obstacles=[o.id for o in self.tracker.obstacles],
                               time_ms=round((time.perf_counter() - t0) * 1e3, 3))
        previous = self._route
        self._route, self._route_error = route, None
        if previous is not None and not forced and np.array_equal(previous.waypoints, route.waypoints):
            return None
        return self._event("route", frame, route={"waypoints_m": np.round(route.waypoints, 6).tolist(),
                                                  "length_m": round(route.length, 6), "planner": route.planner,
                                                  "replanned": bool(route.replanned)},
                           status=route.status, reason=None, error=None, incremental=incremental,
                           obstacles=[o.id for o in self.tracker.obstacles],
                           time_ms=round((time.perf_counter() - t0) * 1e3, 3))

    # -- events ------------------------------------------------------------------------------------
    def _event(self, kind: str, frame: Frame | None = None, **fields: Any) -> Event:
        self._seq += 1
        event = {"type": kind, "seq": self._seq, "stream": self.source.name,
                 "frame": None if frame is None else int(frame.number),
                 "source_time_ms": None if frame is None else round(float(frame.time_ms), 3),
                 "wall_time": round(time.time(), 6),
                 "latency_ms": None if frame is None else round((time.perf_counter() - frame.captured) * 1e3, 3)}
        event.update(fields)
        return event


def watch(source: Any, calibration: Calibration | str | os.PathLike[str], **options: Any) -> Iterator[Event]:
    """The events of watching ``source`` (see :class:`Watcher` for the options).

    >>> for event in watch("recording.avi", "calibration.json", hysteresis="3"):  # doctest: +SKIP
    ...     print(event["type"], event["frame"])
    """
    return Watcher(source, calibration, **options).events()


def changed_boxes(changed: np.ndarray, block: int) -> list[tuple[int, int, int, int]]:
    """The boxes ``(x0, y0, x1, y1)`` (frame pixels, x1 and y1 excluded) around the changed samples
    of a thumbnail taken every ``block`` pixels (``changed``: (h, w) uint8, non-zero where changed),
    one per 8-connected group of CHANGE_POOL x CHANGE_POOL samples with a change, a sample's block
    wider on every side (a sample reads only part of its block)."""
    h, w = changed.shape
    # (a 0/255 mask's area mean stays non-zero wherever one sample changed)
    pooled = cv2.resize(changed, (max(1, w // CHANGE_POOL), max(1, h // CHANGE_POOL)), interpolation=cv2.INTER_AREA)
    fy, fx = h / pooled.shape[0], w / pooled.shape[1]
    _, _, stats, _ = cv2.connectedComponentsWithStats(pooled, connectivity=8)
    b = block
    return [(int(x * fx) * b - b, int(y * fy) * b - b, math.ceil((x + bw) * fx) * b + b, math.ceil((y + bh) * fy) * b + b)
            for x, y, bw, bh, _ in stats[1:].tolist()]


def refreshed(old: np.ndarray, new: np.ndarray, kept_reads: np.ndarray | None, block: int) -> np.ndarray:
    """The thumbnail to compare the next frames with after part of a frame was detected again:
    ``new`` wherever no kept cell reads the frame (``kept_reads``, boxes in frame pixels), ``old``
    where one does, so that each sample stays the one the cells reading it were decided on."""
    if kept_reads is None:
        return new
    h, w = new.shape[:2]
    r0 = np.clip(np.floor(kept_reads[:, 1] / block).astype(np.int64) - 1, 0, h).tolist()
    c0 = np.clip(np.floor(kept_reads[:, 0] / block).astype(np.int64) - 1, 0, w).tolist()
    r1 = np.clip(np.floor(kept_reads[:, 3] / block).astype(np.int64) + 2, 0, h).tolist()
    c1 = np.clip(np.floor(kept_reads[:, 2] / block).astype(np.int64) + 2, 0, w).tolist()
    kept = np.zeros((h, w), bool)
    for a, b, c, d in zip(r0, r1, c0, c1):
        kept[a:b, c:d] = True
    return np.where(kept if new.ndim == 2 else kept[..., None], old, new)
