"""Calibration on the empty floor (paper section 2.2): :func:`calibrate` (calibrate.py), the
calibration file (file.py), the contours measured (shapes.py) and the match threshold
(threshold.py). The symbol grid it fits is :mod:`sbplan.detection.grid`."""

from .calibrate import DEFAULT_STAGES, calibrate, update_calibration
from .file import FORMAT, Calibration, load_calibration
from .shapes import Shapes, extract_shapes, length_filter_steps
from .threshold import confuser_distances, derive_threshold, match_threshold

__all__ = ["DEFAULT_STAGES", "FORMAT", "Calibration", "Shapes", "calibrate", "confuser_distances",
           "derive_threshold", "extract_shapes", "length_filter_steps", "load_calibration", "match_threshold",
           "update_calibration"]
