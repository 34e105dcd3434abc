"""Moved to :mod:`sbplan.registry` (plugin manager, stage registry, lookup API); this path stays
because the docs showed ``sbplan.plugins.registry()`` and ``from sbplan import plugins``."""

from .registry import *  # noqa: F401,F403
