"""Built-in planners of sbplan, registered through the sbplan entry-point group like any plugin.

The exact planner lives in the core (``sbplan.planning.aux_corner``: ``plan`` and ``replan`` use
its search, and OMPL runs it as an ``ompl.base.Planner``); this plugin only registers it. The OMPL
stages (``ompl_stages``) import OMPL when they first solve, not when the registry is built.
"""

from sbplan.hookspecs import hookimpl
from sbplan.planning.aux_corner import AuxCornerPlanner

from .ompl_stages import STAGES


@hookimpl
def sbplan_register_stages(registry):
    registry.add(AuxCornerPlanner)
    for cls in STAGES:
        registry.add(cls)
