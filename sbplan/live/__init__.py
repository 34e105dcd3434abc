"""Live use: watch a camera stream and keep the obstacles and the route current.

``sbplan watch SOURCE -c CALIBRATION.json`` and its Python form::

    from sbplan.live import Watcher
    watcher = Watcher("recording.avi", "calibration.json", hysteresis="3")
    for event in watcher.events():
        ...                      # dicts: the JSON lines of ``sbplan watch``
    watcher.state                # the current LiveState, from any thread

The pieces: :mod:`~sbplan.live.sources` (what frames come from), :mod:`~sbplan.live.reader`
(the reader thread: latest frame, reopening), :mod:`~sbplan.live.tracking` (hysteresis, lasting
obstacle ids), :mod:`~sbplan.live.watcher` (the pipeline and its events). The events' JSON Schema
is :func:`events_schema`. See docs/live.md.
"""

from __future__ import annotations

import json
from importlib import resources

from .reader import Frame, FrameReader, Notice, ReaderStats
from .sources import (FolderSource, IterableSource, Read, Source, SourceError, VideoSource, open_source,
                      paced)
from .tracking import CellHysteresis, Hysteresis, ObstacleTracker
from .watcher import EXIT_CODES, LiveState, Watcher, watch

__all__ = ["CellHysteresis", "EXIT_CODES", "FolderSource", "Frame", "FrameReader", "Hysteresis", "IterableSource",
           "LiveState", "Notice", "ObstacleTracker", "Read", "ReaderStats", "Source", "SourceError", "VideoSource",
           "Watcher", "events_schema", "open_source", "paced", "watch"]


def events_schema() -> dict:
    """The JSON Schema (draft 2020-12) every event of :meth:`Watcher.events` follows."""
    text = resources.files(__package__).joinpath("schemas/events.schema.json").read_text(encoding="utf-8")
    return json.loads(text)
