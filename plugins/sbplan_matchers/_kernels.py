"""The Fourier descriptors' compiled loop (numba): from each outline's spectrum to its descriptor.

After the FFT (numpy's), a frame's few dozen outlines need their orientation, the kept
coefficients, their amplitudes and the chirality invariants: as numpy expressions a dozen calls,
each costing more than its arithmetic. Imported on first use (numba takes a moment; see
``sbplan.detection._kernels``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def descriptors(z, g, gather, harmonics, mirror_terms, out):  # pragma: no cover - compiled
    """:func:`sbplan_matchers.fourier.fourier_descriptors` from the samples ``z`` (m, n) complex and
    their FFT ``g`` (m, n): the coefficients at ``gather`` (2, F) (row 0 for outlines running
    counter-clockwise as displayed, row 1 for clockwise ones: the shoelace on the samples says
    which), amplitudes over the first harmonic's, then the chirality invariants, into ``out``
    (m, harmonics + mirror_terms). Returns the index of the first outline with no first harmonic
    (below 1e-12 of its largest coefficient), or -1."""
    m, n = z.shape
    c = np.empty(gather.shape[1], np.complex128)
    for k in range(m):
        area2 = z[k, n - 1].imag * z[k, 0].real - z[k, n - 1].real * z[k, 0].imag
        for j in range(n - 1):
            area2 += z[k, j].imag * z[k, j + 1].real - z[k, j].real * z[k, j + 1].imag
        row = 1 if area2 < 0 else 0
        largest = 0.0
        for f in range(c.shape[0]):
            # c_k = conj(G_-k) (see _coefficients), unscaled: only ratios of them are kept
            c[f] = np.conj(g[k, gather[row, f]])
            largest = max(largest, abs(c[f]))
        first = abs(c[0])
        if not first > 1e-12 * largest:
            return k
        for f in range(harmonics):
            out[k, f] = abs(c[f + 1]) / first
        square = c[0] * c[0]
        for j in range(mirror_terms):
            q = c[harmonics + 1 + j] * c[harmonics + 1 + mirror_terms + j] / square
            size = abs(q)
            out[k, harmonics + j] = q.imag / math.sqrt(size) if size > 0 else 0.0
    return -1
