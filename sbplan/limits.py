"""Limits on what one command may ask of the machine, and how to raise them.

A typo (``--nav2-resolution 0.00001``) or a hostile file (a 950 KB PNG that decodes to 30000 x
30000 pixels) must end in a clear error, not in a machine that swaps until the kernel kills the
process. Each limit has a default that ordinary floors and cameras stay far below, and an
environment variable that raises (or lowers) it:

==========================  ===========================  =====================================================
limit                       environment variable         what it bounds
==========================  ===========================  =====================================================
``image_pixels``            ``SBPLAN_MAX_IMAGE_PIXELS``  pixels of an image read (checked from the file's header
                                                         before it is decoded; a file whose size no header
                                                         gives is not decoded); default 50 million (8K video is 33)
``map_pixels``              ``SBPLAN_MAX_MAP_PIXELS``    pixels of a raster sbplan makes (a nav2 map, an
                                                         occupancy image's obstacles); default 50 million
``obstacle_vertices``       ``SBPLAN_MAX_OBSTACLE_VERTICES``  vertices of all obstacles one plan works on, and
                                                         runs of occupied pixels of an occupancy image before
                                                         they are merged; default 20 000 (the visibility
                                                         cache takes their square in bytes: 400 MB)
==========================  ===========================  =====================================================

Planning's time limit (``--time-limit`` / ``time_limit=``) bounds the route search only; the work
before it (merging an occupancy image's pixels into polygons, preparing the map) is not interrupted
by it and is bounded by ``obstacle_vertices`` instead: at the default, up to about 1.8 s of merging
and 1.6 s of preparing (19 845 vertices; 2 shared cores at load 4).
"""

from __future__ import annotations

import os

from .errors import InputError, LimitError

DEFAULTS: dict[str, int] = {
    "image_pixels": 50_000_000,
    "map_pixels": 50_000_000,
    "obstacle_vertices": 20_000,
}
ENV: dict[str, str] = {
    "image_pixels": "SBPLAN_MAX_IMAGE_PIXELS",
    "map_pixels": "SBPLAN_MAX_MAP_PIXELS",
    "obstacle_vertices": "SBPLAN_MAX_OBSTACLE_VERTICES",
}


def limit(name: str) -> int:
    """The limit ``name`` (a key of :data:`DEFAULTS`): its environment variable when set, else the
    default."""
    raw = os.environ.get(ENV[name])
    if raw is None or not raw.strip():
        return DEFAULTS[name]
    try:
        value = int(float(raw))
    except ValueError:
        raise InputError(f"{ENV[name]}: expected a positive number, got {raw!r}") from None
    if value <= 0:
        raise InputError(f"{ENV[name]}: expected a positive number, got {raw!r}")
    return value


def check(name: str, value: float, what: str, hint: str = "") -> None:
    """Raise :class:`LimitError` when ``value`` exceeds the limit ``name``; the message says what
    asked for it, the limit, and how to raise it."""
    top = limit(name)
    if not value <= top:
        tip = f"{hint}; " if hint else ""
        raise LimitError(f"{what}: more than the limit of {top:,} {name.replace('_', ' ')}; "
                         f"{tip}raise it with {ENV[name]}=N if this is intended")
