"""Choosing the reference symbol (paper section 3) and printing it.

- :mod:`sbplan.symbols.rank`: render candidates as the camera sees them, the paper's equations
  (2)-(4), a measured regularity score (condition 3) and a confusion margin against noise contours.
- :mod:`sbplan.symbols.noise`: the noise set (lighting blobs, circles, ellipses, partly hidden copies,
  obstacle-edge fragments).
- :mod:`sbplan.symbols.tile`: printable floor tiles (SVG, PDF, PNG) with crop marks.
- :mod:`sbplan.symbols.terminal`: a symbol drawn with Unicode half-blocks or braille.
- :mod:`sbplan.symbols.plots`: the figures (FD amplitudes, mean and variance, distance heat map).

Submodules are imported on use; ``import sbplan.symbols`` itself is cheap.
"""

from __future__ import annotations

__all__ = ["rank", "noise", "tile", "terminal", "plots", "raster"]
