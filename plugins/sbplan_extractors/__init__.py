"""Built-in extractors of sbplan, registered through the sbplan entry-point group like any plugin.

- ``oke``: the paper's 2x2-window contour extraction, vectorized with numpy.
- ``opencv``: OpenCV's border following, the fast default.
"""

from sbplan.hookspecs import hookimpl

from .oke import OkeExtractor, find_contours_oke
from .opencv import OpenCVExtractor, find_contours_opencv

__all__ = ["OkeExtractor", "OpenCVExtractor", "find_contours_oke", "find_contours_opencv"]


@hookimpl
def sbplan_register_stages(registry):
    registry.add(OkeExtractor)
    registry.add(OpenCVExtractor)
