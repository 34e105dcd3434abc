"""Built-in footprint stages of sbplan, registered through the sbplan entry-point group like any plugin."""

from sbplan.hookspecs import hookimpl


@hookimpl
def sbplan_register_stages(registry):
    from .cells import CellsFootprint
    from .pixels import PixelsFootprint

    registry.add(CellsFootprint)
    registry.add(PixelsFootprint)
