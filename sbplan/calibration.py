"""Moved to :mod:`sbplan.detection.calibration`; this path stays for the imports the docs showed."""

from .detection.calibration import *  # noqa: F401,F403
from .detection.calibration import __all__  # noqa: F401
