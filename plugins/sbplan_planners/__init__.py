"""Built-in planners of sbplan, registered through the sbplan entry-point group like any plugin."""

from sbplan.hookspecs import hookimpl


@hookimpl
def sbplan_register_stages(registry):
    from .aux_corner import AuxCornerPlanner
    from .ompl_stages import STAGES

    registry.add(AuxCornerPlanner)
    for cls in STAGES:
        registry.add(cls)
