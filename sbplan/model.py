"""Moved to :mod:`sbplan.contours` (``Contour``, ``as_points``, ``FREEMAN_STEPS``); this path stays
because third-party plugins import ``from sbplan.model import ...``."""

from .contours import *  # noqa: F401,F403
