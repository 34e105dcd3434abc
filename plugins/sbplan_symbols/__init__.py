"""Built-in candidate reference symbols (parametric polygons), registered through the sbplan entry-point group."""

from __future__ import annotations

from sbplan.hookspecs import hookimpl


@hookimpl
def sbplan_register_symbols(registry) -> None:
    from .shapes import catalogue

    for name, (description, rings) in catalogue().items():
        registry.add_symbol(name, rings, description=description)
