"""Detection (paper sections 2.2 and 4): calibration on the empty floor, then which cells of later
frames are occupied and the obstacles they form.

calibration/ fits a :class:`Calibration`; detector.py runs the hot path (:class:`Detector`) and
result.py holds what it gives; grid.py, bands.py, outline_checks.py, obstacles.py and exports.py
are its steps and outputs.
"""

from .calibration import Calibration, calibrate, load_calibration
from .detector import Detector, detect
from .result import FORMAT, CellDetection, Detection

__all__ = ["FORMAT", "Calibration", "CellDetection", "Detection", "Detector", "calibrate", "detect",
           "load_calibration"]
