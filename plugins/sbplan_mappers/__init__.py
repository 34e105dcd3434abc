"""Built-in occupancy mappers of sbplan, registered through the sbplan entry-point group like any plugin."""

from sbplan.hookspecs import hookimpl


@hookimpl
def sbplan_register_stages(registry):
    from .blocks import BlocksMapper
    from .cells import CellsMapper

    registry.add(BlocksMapper)
    registry.add(CellsMapper)
