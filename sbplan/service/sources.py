"""Live sources for ``sbplan serve --source``: where frames come from when they are not posted.

A source is anything with a ``name`` and ``frames(stop)``, an iterator of :class:`Frame` (an
image to detect) and :class:`Skipped` (a frame that could not be read), that ends when the source
ends or ``stop`` is set. :class:`SourceRunner` feeds the frames to the service on a thread of its
own. Today there is one kind, :class:`FolderSource` (the images of a folder, in name order). The
live package (``sbplan watch``: cameras, video files, streams) plugs in as another branch of
:func:`open_source` returning such an object.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Protocol

import numpy as np

from ..errors import InputError, SbplanError
from . import models
from .core import Service

#: File names a folder source reads (OpenCV decodes them; the service accepts PNG and JPEG).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True)
class Frame:
    """One frame: ``data`` is PNG/JPEG bytes or a grayscale (H, W) uint8 image."""

    name: str | None
    data: bytes | np.ndarray
    received: float


@dataclass(frozen=True)
class Skipped:
    """A frame the source could not read."""

    name: str | None
    message: str


class FrameSource(Protocol):
    name: str

    def frames(self, stop: threading.Event) -> Iterator[Frame | Skipped]: ...


class FolderSource:
    """The PNG and JPEG images of a folder, sorted by name, one every ``interval`` seconds.

    Parameters
    ----------
    folder : path
    interval : float
        Seconds between two frames (0: as fast as they are detected).
    """

    def __init__(self, folder: str | Path, *, interval: float = 0.0):
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise InputError(f"source: {folder} is not a folder")
        if not (interval >= 0):
            raise InputError(f"interval: must be >= 0 seconds, got {interval!r}")
        self.interval = float(interval)
        self.paths = sorted(p for p in self.folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not self.paths:
            raise InputError(f"source: no {'/'.join(IMAGE_SUFFIXES)} images in {folder}")
        self.name = f"folder:{self.folder.name}"

    def frames(self, stop: threading.Event) -> Iterator[Frame | Skipped]:
        for i, path in enumerate(self.paths):
            if i and stop.wait(self.interval):
                return
            if stop.is_set():
                return
            try:
                yield Frame(path.name, path.read_bytes(), time.time())
            except OSError as exc:
                yield Skipped(path.name, f"{path.name}: cannot be read ({exc.strerror or exc})")


def open_source(spec: str, *, interval: float = 0.0) -> FrameSource:
    """The source ``spec`` names: today a folder of images."""
    if Path(spec).is_dir():
        return FolderSource(spec, interval=interval)
    raise InputError(f"source: {spec!r} is not a folder of images; cameras, video files and streams come with "
                     f"the live package (sbplan watch), which this build does not have")


class SourceRunner:
    """Feeds a source's frames to the service on its own thread until the source ends or
    :meth:`stop`. Rejected frames are counted (the service sends a ``frame-rejected`` event for
    each); the end sends a ``source`` event."""

    def __init__(self, service: Service, source: FrameSource):
        self.service, self.source = service, source
        self.frames = self.rejected = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sbplan-source", daemon=True)

    def start(self) -> "SourceRunner":
        self.service.source_name = self.source.name
        self._thread.start()
        return self

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)

    def _run(self) -> None:
        name = self.source.name
        try:
            for item in self.source.frames(self._stop):
                if isinstance(item, Skipped):
                    self.rejected += 1
                    self.service.publish(models.FrameRejectedEvent, source=name, name=item.name, code="unreadable",
                                         message=item.message)
                    continue
                try:
                    self.service.submit_frame(item.data, source=name, name=item.name, received=item.received).result()
                    self.frames += 1
                except SbplanError:
                    self.rejected += 1  # the service sent the frame-rejected event
        except Exception as exc:  # noqa: BLE001  (a source that fails is reported, the service stays up)
            self._end("failed", f"{name} failed: {exc}")
            return
        self._end("ended", f"{name} ended" + (" (stopped)" if self._stop.is_set() else ""))

    def _end(self, state: str, message: str) -> None:
        try:
            self.service.publish(models.SourceEvent, source=self.source.name, state=state, frames=self.frames,
                                 rejected=self.rejected, message=message)
        except RuntimeError:
            pass  # the service is shutting down
