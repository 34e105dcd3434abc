"""Every hook a plugin can implement.

A plugin is a module (or object) found through the ``sbplan`` entry-point group, e.g. in its
``pyproject.toml``::

    [project.entry-points.sbplan]
    my_matchers = "my_package.plugin"

and implementing hooks with :data:`hookimpl`::

    from sbplan.hookspecs import hookimpl

    @hookimpl
    def sbplan_register_stages(registry):
        registry.add(MyMatcher)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import pluggy

if TYPE_CHECKING:
    from .registry import StageRegistry

PROJECT = "sbplan"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def sbplan_register_stages(registry: "StageRegistry") -> None:
    """Add stage classes to the registry.

    Call ``registry.add(cls)`` once per class; ``cls`` subclasses one of the contracts in
    :mod:`sbplan.contracts` and has a unique ``name`` within its kind. The kind comes from the class.
    """


@hookspec
def sbplan_register_symbols(registry: "StageRegistry") -> None:
    """Add candidate reference symbols (for the scene renderer, calibration and symbol ranking).

    Call ``registry.add_symbol(name, polygon, description=...)`` where ``polygon`` is an
    ``(N, 2)`` array of vertices ``(x, y)`` of the symbol's outline in a unit box (y down), or a
    list of such arrays where the first is the outline and the rest are holes.
    """
