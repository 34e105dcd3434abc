"""Where frames come from: a video file, a folder of images, a camera, a stream URL, or Python.

Every source is opened and read through OpenCV (``cv2.VideoCapture``, its FFmpeg backend for
files and URLs; ``cv2.imread`` for a folder's images): sbplan decodes nothing itself.

A :class:`Source` describes what to open; :meth:`Source.open` gives a :class:`Capture`, whose
:meth:`~Capture.read` returns one :class:`Read` at a time. A source is opened again after a fault
(:mod:`sbplan.live.reader`), at the frame after the last one delivered where it can seek (files,
folders), or wherever the stream is now (cameras, URLs).
"""

from __future__ import annotations

import os
import re
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import cv2
import numpy as np

from ..errors import InputError, SbplanError
from ..imageio import as_gray

# FFmpeg's own complaint about a broken frame would land on the terminal (over the TUI); the watch
# counts such frames and reports them in its events. OpenCV reads this once, when it first uses
# FFmpeg, so it is set on import (a value the user set is kept).
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

#: Image endings a folder source reads, in any letter case.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp")
#: Consecutive undecodable reads after which a file is taken to have ended (OpenCV's FFmpeg
#: backend skips a broken frame per read, so a run this long is the end or a broken file).
MAX_FAILED_READS = 25


class SourceError(SbplanError):
    """A source cannot be opened (now); live sources are tried again with backoff."""

    exit_code = 3


@dataclass(frozen=True)
class Read:
    """What one read gave.

    Attributes
    ----------
    status : str
        ``"frame"``, ``"corrupt"`` (a frame that could not be decoded: skipped), ``"end"`` (the
        file or folder has no more frames) or ``"lost"`` (the stream failed: open it again).
    image : ndarray (H, W) uint8 or None
        The frame in grey levels.
    number : int or None
        The frame's number in the source (from its timestamp or file name), counting from 0.
    time_ms : float or None
        The source's timestamp of the frame (``CAP_PROP_POS_MSEC``, or number / fps for a
        folder); None for live sources (the reader stamps them with the wall clock).
    corrupt : int
        Frames that could not be decoded and were skipped just before this read (a video's
        broken frames; a folder reports each as a read of status ``"corrupt"``).
    """

    status: str
    image: np.ndarray | None = None
    number: int | None = None
    time_ms: float | None = None
    corrupt: int = 0


class Capture:
    """One open source. :meth:`read` blocks until the next frame (or fault)."""

    def read(self) -> Read:  # pragma: no cover - interface
        raise NotImplementedError

    def close(self) -> None:
        """Release the source (idempotent)."""


class Source:
    """What to open.

    Attributes
    ----------
    name : str
        How events and messages name it.
    kind : str
        ``"file"``, ``"folder"``, ``"camera"``, ``"url"`` or ``"python"``.
    live : bool
        A live source delivers frames as they happen: the reader always keeps the latest one and
        frames are stamped with the wall clock. Files and folders are read frame by frame unless
        replayed in real time.
    fps : float or None
        The source's frame rate, when it states one.
    """

    name: str = "source"
    kind: str = "python"
    live: bool = True
    fps: float | None = None

    def open(self, after: int | None = None) -> Capture:  # pragma: no cover - interface
        """Open the source, positioned after frame ``after`` where it can seek (None: at its start).

        Raises
        ------
        SourceError
            The source cannot be opened now.
        """
        raise NotImplementedError


def _gray(image: np.ndarray) -> np.ndarray:
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.ndim == 3 and image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY)
    if image.dtype != np.uint8:
        return as_gray(image)
    return image


# -- OpenCV VideoCapture: files, cameras, URLs -------------------------------------------------------
class VideoSource(Source):
    """A video file, camera index or stream URL read by ``cv2.VideoCapture``.

    Parameters
    ----------
    target : str or int
        A path, a camera index, or a URL (``rtsp://``, ``http://`` ...).
    timeout : float
        Seconds FFmpeg may wait to open a URL or for its next packet before the read fails
        (``CAP_PROP_OPEN_TIMEOUT_MSEC``, ``CAP_PROP_READ_TIMEOUT_MSEC``): a stalled network
        stream then fails and is opened again, instead of blocking for FFmpeg's default 30 s.
    """

    def __init__(self, target: str | int, *, timeout: float = 5.0):
        self.target = target
        self.timeout = float(timeout)
        if isinstance(target, int):
            self.kind, self.live, self.name = "camera", True, f"camera {target}"
        elif re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*://", str(target)):
            self.kind, self.live, self.name = "url", True, _redact(str(target))
        else:
            path = Path(target)
            if not path.is_file():
                raise InputError(f"source: {target}: no such video file, folder, camera index or URL")
            self.kind, self.live, self.name = "file", False, str(target)
        self.fps = None
        self.frame_count: int | None = None

    def open(self, after: int | None = None) -> "VideoCapture":
        if self.kind == "camera":
            cap = cv2.VideoCapture(int(self.target))
        else:
            params = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, int(self.timeout * 1000),
                      cv2.CAP_PROP_READ_TIMEOUT_MSEC, int(self.timeout * 1000)]
            cap = cv2.VideoCapture(str(self.target), cv2.CAP_FFMPEG, params)
        if not cap.isOpened():
            cap.release()
            if self.kind == "file":
                raise InputError(f"source: {self.name}: OpenCV cannot read this video file")
            raise SourceError(f"source: {self.name}: cannot open")
        fps = cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(fps) if fps and np.isfinite(fps) and 0 < fps < 1000 else None
        if self.kind == "file":
            count = cap.get(cv2.CAP_PROP_FRAME_COUNT)
            self.frame_count = int(count) if count and count > 0 else None
            if after is not None:
                # MJPG and intra-only files seek exactly; others land on the frame FFmpeg finds
                cap.set(cv2.CAP_PROP_POS_FRAMES, after + 1)
        return VideoCapture(self, cap, after)


class VideoCapture(Capture):
    def __init__(self, source: VideoSource, cap: Any, after: int | None):
        self.source, self.cap = source, cap
        self.last = after
        self._lock = threading.Lock()

    def read(self) -> Read:
        cap, src = self.cap, self.source
        if cap is None:
            return Read("end")
        skipped = 0
        while True:
            ok, image = cap.read()
            if ok and image is not None:
                break
            if src.live:
                return Read("lost")
            # OpenCV's FFmpeg backend gives False both for a frame it cannot decode (the next read
            # goes on after it) and at the end of the file: the frame count tells them apart, or
            # else a long run of failures is the end
            skipped += 1
            count, last = src.frame_count, -1 if self.last is None else self.last
            if count is not None and last + skipped >= count:
                return Read("end", corrupt=skipped - 1)
            if skipped > MAX_FAILED_READS:
                return Read("end")
        if src.live:
            return Read("frame", _gray(image), corrupt=skipped)
        t = cap.get(cv2.CAP_PROP_POS_MSEC)
        if src.fps:
            number = int(round(t * src.fps / 1000.0))
        else:
            number = (0 if self.last is None else self.last + 1) + skipped
        if self.last is not None and number <= self.last:
            number = self.last + 1  # a timestamp that did not advance: still the next frame
        self.last = number
        return Read("frame", _gray(image), number, float(t), corrupt=skipped)

    def close(self) -> None:
        with self._lock:
            if self.cap is not None:
                self.cap.release()
                self.cap = None


def _redact(url: str) -> str:
    """A URL without its password (events and logs name the source)."""
    return re.sub(r"(://[^:/@]+):[^@/]*@", r"\1:***@", url)


# -- a folder of images -----------------------------------------------------------------------------
class FolderSource(Source):
    """The images of a folder, in the order of their names, read by ``cv2.imread``.

    When every name ends in a number (``frame-00012.png``), that number is the frame's number, so
    a gap in the numbering is a missing frame; otherwise frames are numbered in name order.
    Timestamps are number / ``fps``.
    """

    kind, live = "folder", False
    fps: float  # always stated: frames are timed at it

    def __init__(self, folder: str | os.PathLike, *, fps: float = 10.0):
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise InputError(f"source: {folder}: no such folder")
        if not (isinstance(fps, (int, float)) and 0 < fps <= 1000):
            raise InputError(f"fps: expected a number in (0, 1000], got {fps!r}")
        self.name, self.fps = str(folder), float(fps)
        files = sorted(p for p in self.folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
        if not files:
            raise InputError(f"source: {folder}: no images ({', '.join(IMAGE_SUFFIXES)})")
        found = [re.search(r"(\d+)\D*$", p.stem) for p in files]
        numbers = [int(m.group(1)) for m in found if m is not None]
        if len(numbers) == len(files) and len(set(numbers)) == len(files):
            pairs = sorted(zip(numbers, files))
        else:
            pairs = list(enumerate(files))
        self.files: list[tuple[int, Path]] = pairs

    def open(self, after: int | None = None) -> "FolderCapture":
        start = 0 if after is None else next((i for i, (n, _) in enumerate(self.files) if n > after), len(self.files))
        return FolderCapture(self, start)


class FolderCapture(Capture):
    def __init__(self, source: FolderSource, start: int):
        self.source, self.at = source, start

    def read(self) -> Read:
        files = self.source.files
        if self.at >= len(files):
            return Read("end")
        number, path = files[self.at]
        self.at += 1
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if image is None:
            return Read("corrupt", None, number)
        return Read("frame", image, number, number * 1000.0 / self.source.fps)


# -- Python: arrays from an iterable or a callable --------------------------------------------------
class IterableSource(Source):
    """Frames from Python: an iterable of images (gray or BGR arrays), or of ``(time_ms, image)``
    pairs. ``None`` in place of an image is a corrupt frame. Live by default (stamped with the wall
    clock); ``live=False`` numbers and times the frames as a file would (at ``fps``).

    The iterable is consumed once: opening the source again goes on where it stopped.
    """

    kind = "python"

    def __init__(self, frames: Iterable, *, live: bool = True, fps: float | None = None, name: str = "python"):
        self._it: Iterator = iter(frames)
        self._lock = threading.Lock()
        self.live, self.fps, self.name = bool(live), fps, name
        self._number = -1

    def open(self, after: int | None = None) -> Capture:
        return _IterCapture(self)


class _IterCapture(Capture):
    def __init__(self, source: IterableSource):
        self.source = source

    def read(self) -> Read:
        src = self.source
        with src._lock:
            try:
                item = next(src._it)
            except StopIteration:
                return Read("end")
            src._number += 1
            number = src._number
        t = None
        if isinstance(item, tuple) and len(item) == 2:
            t, item = float(item[0]), item[1]
        elif not src.live:
            t = number * 1000.0 / (src.fps or 10.0)
        if item is None:
            return Read("corrupt", None, number)
        return Read("frame", _gray(np.asarray(item)), None if src.live else number, t)


def open_source(spec: Any, *, fps: float | None = None, timeout: float = 5.0) -> Source:
    """The :class:`Source` a command-line SOURCE (or a Python object) names.

    Parameters
    ----------
    spec : str, int, path, Source or iterable
        A video file, a folder of images, a camera index (``0``), a URL, a :class:`Source`, or an
        iterable of frames (:class:`IterableSource`).
    fps : float, optional
        Frame rate of a folder (default 10) or an iterable.
    timeout : float
        Open and read timeout of URLs, seconds.
    """
    if isinstance(spec, Source):
        return spec
    if isinstance(spec, bool):
        raise InputError(f"source: expected a path, camera index or URL, got {spec!r}")
    if isinstance(spec, int):
        return VideoSource(spec, timeout=timeout)
    if isinstance(spec, (str, os.PathLike)):
        text = os.fspath(spec)
        if re.fullmatch(r"\d{1,3}", text) and not Path(text).exists():
            return VideoSource(int(text), timeout=timeout)
        if Path(text).is_dir():
            return FolderSource(text, fps=10.0 if fps is None else fps)
        return VideoSource(text, timeout=timeout)
    if isinstance(spec, Iterable) and not isinstance(spec, np.ndarray):
        return IterableSource(spec, fps=fps)
    raise InputError(f"source: expected a path, camera index, URL or frames, got {type(spec).__name__}")


def paced(source: Source, *, speed: float = 1.0, clock: Callable[[], float] = time.monotonic) -> Source:
    """``source`` delivered at its own frame rate times ``speed`` (a file replayed as a camera
    would deliver it): the reader then keeps only the latest frame, as for a live source."""
    return _Paced(source, speed, clock)


class _Paced(Source):
    def __init__(self, inner: Source, speed: float, clock: Callable[[], float]):
        if not (isinstance(speed, (int, float)) and speed > 0):
            raise InputError(f"speed: expected a number > 0, got {speed!r}")
        self.inner, self.speed, self.clock = inner, float(speed), clock
        self.name, self.kind, self.live, self.fps = inner.name, inner.kind, True, inner.fps
        self.paced = True

    def open(self, after: int | None = None) -> Capture:
        return _PacedCapture(self, self.inner.open(after))


class _PacedCapture(Capture):
    def __init__(self, source: _Paced, inner: Capture):
        self.source, self.inner = source, inner
        self.t0: float | None = None
        self.m0 = 0.0

    def read(self) -> Read:
        r = self.inner.read()
        if r.status == "frame" and r.time_ms is not None:
            now = self.source.clock()
            if self.t0 is None:
                self.t0, self.m0 = now, r.time_ms
            due = self.t0 + (r.time_ms - self.m0) / 1000.0 / self.source.speed
            if due > now:
                time.sleep(due - now)
        return r

    def close(self) -> None:
        self.inner.close()
