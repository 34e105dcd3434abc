"""Moved to :mod:`sbplan.contracts` (the stage contracts); this path stays because third-party
plugins written against the plugin guide import ``from sbplan.stages import ...``."""

from .contracts import *  # noqa: F401,F403
