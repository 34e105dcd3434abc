"""Moved to :mod:`sbplan.contours` (``Contour``, ``as_points``, ``FREEMAN_STEPS``) and
:mod:`sbplan.contracts` (``as_descriptors``); this path stays because third-party plugins import
``from sbplan.model import ...``."""

from .contours import *  # noqa: F401,F403
from .contracts import as_descriptors  # noqa: F401
