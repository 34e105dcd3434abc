"""sbplan-elliptic-fourier: an out-of-tree sbplan plugin adding the ``elliptic-fourier`` matcher.

Installed with ``pip install ./plugins/sbplan-elliptic-fourier``, it is found through the ``sbplan``
entry-point group declared in its pyproject.toml; nothing in sbplan names it.
"""

from sbplan.hookspecs import hookimpl

from .matcher import EllipticFourierMatcher, elliptic_coefficients, elliptic_descriptors, normalize_coefficients

__all__ = ["EllipticFourierMatcher", "elliptic_coefficients", "elliptic_descriptors", "normalize_coefficients"]
__version__ = "0.1.0"


@hookimpl
def sbplan_register_stages(registry):
    registry.add(EllipticFourierMatcher)
