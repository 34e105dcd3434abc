"""Log filtering shared by the benchmarks."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator


@contextlib.contextmanager
def camera_warnings_muted() -> Iterator[None]:
    """Keep the detector's "camera moved" warnings out of a benchmark's output meanwhile.

    The benchmarks move the camera on purpose (the camera conditions, the watch stream's bump) and
    report each movement in their tables; the warnings would only interleave with the progress
    lines (one per detector, so one per stream). The logger is left as it was found."""

    def not_camera_warning(record: logging.LogRecord) -> bool:
        return not (record.levelno == logging.WARNING and "camera" in getattr(record, "data", {}))

    detector_log = logging.getLogger("sbplan.detection.detector")
    detector_log.addFilter(not_camera_warning)
    try:
        yield
    finally:
        detector_log.removeFilter(not_camera_warning)
