"""Built-in matchers of sbplan, registered through the sbplan entry-point group like any plugin."""

from sbplan.hookspecs import hookimpl


@hookimpl
def sbplan_register_stages(registry):
    from .centroid_distance import CentroidDistanceMatcher
    from .fourier import FourierMatcher
    from .hu_moments import HuMomentsMatcher

    registry.add(FourierMatcher)
    registry.add(CentroidDistanceMatcher)
    registry.add(HuMomentsMatcher)
