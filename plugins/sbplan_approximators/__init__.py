"""Built-in approximators of sbplan, registered through the sbplan entry-point group like any plugin."""

from sbplan.hookspecs import hookimpl


@hookimpl
def sbplan_register_stages(registry):
    from .douglas_peucker import DouglasPeucker
    from .kka import KKA

    registry.add(KKA)
    registry.add(DouglasPeucker)
