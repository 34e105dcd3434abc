"""Moved to :mod:`sbplan.polygons` (areas, centres, resampling, ``PolygonBatch``); this path stays
because third-party plugins import ``from sbplan.geometry import ...``."""

from .polygons import *  # noqa: F401,F403
