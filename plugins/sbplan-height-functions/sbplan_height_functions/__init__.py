"""sbplan-height-functions: an out-of-tree sbplan plugin adding the ``height-functions`` matcher.

Installed with ``pip install ./plugins/sbplan-height-functions``, it is found through the ``sbplan``
entry-point group declared in its pyproject.toml; nothing in sbplan names it.
"""

from sbplan.hookspecs import hookimpl

from .matcher import HeightFunctionsMatcher, height_descriptors, mirror_descriptors, segment_weights, shape_complexity

__all__ = ["HeightFunctionsMatcher", "height_descriptors", "mirror_descriptors", "segment_weights", "shape_complexity"]
__version__ = "0.1.0"


@hookimpl
def sbplan_register_stages(registry):
    registry.add(HeightFunctionsMatcher)
