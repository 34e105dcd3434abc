"""The paper's Fourier descriptors (FDs) and its equation (2) distance."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import ClassVar, Sequence

import numpy as np

from sbplan.contours import as_points
from sbplan.contracts import DescriptorMatcher, as_descriptors, option
from sbplan.errors import ContourError, InputError
from sbplan.polygons import resample_complex

__all__ = ["FourierMatcher", "fourier_coefficients", "fourier_descriptors"]


def fourier_coefficients(outlines: Sequence[np.ndarray], freqs, *, samples: int = 128) -> np.ndarray:
    """Orientation-normalized Fourier coefficients of many closed outlines.

    Each outline is resampled at ``samples`` points equally spaced by arc length and read as the
    complex numbers ``w = x - i*y`` (the picture as displayed, y up), so that a counter-clockwise
    outline *as displayed* turns positively. Outlines that run clockwise (holes, reversed vertex
    lists) are reversed, which maps coefficient ``c_k`` to ``c_-k``; after that an outer boundary
    and a hole of the same shape, or a polygon and its reversed vertex list, have the same
    coefficients up to the start-point phase.

    Parameters
    ----------
    outlines : sequence of array_like of shape (N_i, 2)
        Closed outlines ``(x, y)``, N_i >= 3.
    freqs : sequence of int
        The frequencies wanted, each with ``|k| < samples / 2``.
    samples : int
        Arc-length samples per outline.

    Returns
    -------
    ndarray of shape (m, len(freqs)), complex128
        ``c[:, i]`` is the coefficient of frequency ``freqs[i]``, ``(1/samples) sum_j w_j
        exp(-2 pi i k j / samples)``. Not scale-normalized.
    """
    k = np.asarray(freqs, dtype=np.int64)
    if k.ndim != 1 or (2 * np.abs(k) >= samples).any():
        raise InputError(f"freqs: expected a 1-D list of frequencies with |k| < samples / 2 = {samples / 2:g}")
    return _coefficients(resample_complex(outlines, samples), _gather_plan(tuple(k.tolist()), samples), samples)


@functools.lru_cache(maxsize=16)
def _gather_plan(freqs: tuple[int, ...], samples: int) -> np.ndarray:
    """Where coefficient ``freqs[i]`` sits in the FFT of ``x + i y`` (see :func:`_coefficients`):
    row 0 for outlines running counter-clockwise as displayed, row 1 for clockwise ones."""
    k = np.asarray(freqs, dtype=np.int64)
    # c_k = conj(G_-k); a reversed outline has c_k -> c_-k = conj(G_k)
    return np.stack([-k % samples, k % samples])


def _coefficients(z: np.ndarray, plan: np.ndarray, samples: int = 0) -> np.ndarray:
    """:func:`fourier_coefficients` from the samples ``z = x + i y`` (m, samples); without
    ``samples``, times the number of samples (the FFT's sums, not divided)."""
    # One complex FFT gives every coefficient of w = x - i y = conj(z): with G the FFT of z,
    # c_k = (1/n) sum_j conj(z_j) e^(-2 pi i k j / n) = conj(G_-k) / n.
    g = np.fft.fft(z, axis=1)
    # The shoelace on the samples gives the traversal sense (positive = counter-clockwise as
    # displayed, i.e. in the w plane); reversing a clockwise outline swaps c_k and c_-k.
    x, y = z.real, z.imag
    area2 = np.einsum("ij,ij->i", y[:, :-1], x[:, 1:]) - np.einsum("ij,ij->i", x[:, :-1], y[:, 1:]) \
        + y[:, -1] * x[:, 0] - x[:, -1] * y[:, 0]
    rows = np.arange(0, g.size, g.shape[1])[:, None]
    c = np.conjugate(g.ravel()[plan[(area2 < 0).view(np.int8)] + rows])
    if samples:
        c /= samples
    return c


def _frequencies(harmonics: int) -> np.ndarray:
    """The kept frequencies: k = -1..-h_neg and 2..h_pos+1, h_neg = harmonics // 2."""
    h_neg = harmonics // 2
    h_pos = harmonics - h_neg
    return np.concatenate([-np.arange(1, h_neg + 1), np.arange(2, h_pos + 2)])


@functools.lru_cache(maxsize=16)
def _plan(harmonics: int, mirror_terms: int) -> tuple[np.ndarray, np.ndarray]:
    """The kept frequencies and all frequencies needed: [1, kept, 1 + j, 1 - j], j = 2, 3, ..."""
    kept = _frequencies(harmonics)
    j = np.arange(2, mirror_terms + 2)
    return kept, np.concatenate([[1], kept, 1 + j, 1 - j]).astype(np.int64)


@functools.lru_cache(maxsize=16)
def _descriptor_plan(harmonics: int, mirror_terms: int, samples: int) -> tuple[int, np.ndarray]:
    """The number of amplitudes kept and :func:`_gather_plan` of all frequencies needed."""
    kept, freqs = _plan(harmonics, mirror_terms)
    return len(kept), _gather_plan(tuple(freqs.tolist()), samples)


def fourier_descriptors(outlines: Sequence[np.ndarray], *, samples: int = 128, harmonics: int = 20,
                        mirror_terms: int = 4) -> np.ndarray:
    """The FD vectors of many closed outlines, shape (m, harmonics + mirror_terms).

    The first ``harmonics`` entries are the amplitudes ``|c_k| / |c_1|`` for the frequencies of
    :func:`_frequencies` (the paper's amplitude spectrum, scale-normalized by the first harmonic);
    the last ``mirror_terms`` entries are the chirality invariants
    ``Im(q_j) / sqrt(|q_j|)`` with ``q_j = c_(1+j) c_(1-j) / c_1^2``, j = 2, 3, ...: invariant to
    translation, rotation, scale and start point like the amplitudes, but changing sign when the
    shape is mirrored (amplitudes alone cannot tell a shape from its mirror image).
    """
    h, gather = _descriptor_plan(harmonics, mirror_terms, samples)
    z = resample_complex(outlines, samples)
    m = len(z)
    if m == 0:
        return np.zeros((0, harmonics + mirror_terms))
    # One complex FFT gives every coefficient (see _coefficients); the rest is one compiled loop.
    # The descriptor is made of ratios of coefficients, so they are not divided by the samples.
    out = np.empty((m, h + mirror_terms))
    degenerate = _compiled().descriptors(z, np.fft.fft(z, axis=1), gather, h, mirror_terms, out)
    if degenerate >= 0:
        raise ContourError(f"outlines[{degenerate}]: degenerate outline (no first harmonic), it has no "
                           "Fourier descriptor")
    return out


@functools.cache
def _compiled():
    """The compiled loop (``_kernels``), imported on first use: numba takes a moment."""
    from . import _kernels
    return _kernels


@dataclass(kw_only=True, frozen=True)
class FourierMatcher(DescriptorMatcher):
    """The paper's Fourier descriptors and equation (2): ``d = sqrt(sum_k (A_k - B_k)^2)``.

    Descriptor: the closed outline is resampled by arc length (``samples`` points), read as
    complex numbers, orientation-normalized (so holes and outer boundaries of one shape agree),
    transformed by an FFT; the DC term (translation) is dropped, amplitudes are taken (rotation,
    start point) and divided by the first harmonic's amplitude (scale). ``harmonics`` amplitudes
    are kept: k = -1..-10 and k = 2..11 by default. Both signs are kept because a polygon with
    n-fold symmetry concentrates its energy at k = 1 - n and k = 1 + n (a triangle at -2 and 4, a
    square at -3 and 5), so each side carries shape information; k = +1 is left out because after
    scale normalization it is always 1.

    Mirror images: amplitude FDs are blind to mirroring (a mirrored outline traversed in the same
    rotational sense has exactly the same amplitudes). With ``mirror_terms > 0`` the descriptor
    gets that many chirality invariants (see :func:`fourier_descriptors`) that flip sign under
    mirroring, so an asymmetric shape and its mirror image are at a positive distance; set
    ``mirror_terms=0`` for the paper's pure amplitude spectrum.

    Distance: the Euclidean distance of the descriptor vectors, equation (2). It is a fraction of
    the first harmonic's amplitude: 0.1 means the outlines' spectra differ, in total, by a tenth of
    their dominant (ellipse-like) component. ``default_threshold`` is 0.15, three times the largest
    distance measured between re-rasterizations of one random polygon at 40-90 px and any rotation
    (0.05, the RASTER_TOL of tests/test_matchers.py): a fixed camera sees every floor symbol as such
    a re-rasterization. Shapes that are also sheared or bent (the silhouette benchmark,
    docs/benchmarks.md) spread further and overlap other classes near 0.12-0.16. The paper's 0.5 was
    for its own normalization, and calibration derives a threshold from the reference image anyway.
    """

    name: ClassVar[str] = "fourier"
    description: ClassVar[str] = "the paper's Fourier-descriptor amplitudes with the Euclidean distance of eq. (2)"
    default_threshold: ClassVar[float] = 0.15

    samples: int = option(128, "arc-length samples per outline for the FFT (>= 2*harmonics + 8)")
    harmonics: int = option(20, "number of Fourier amplitudes kept (k = -1..-h/2 and 2..h/2+1)")
    mirror_terms: int = option(4, "chirality invariants appended so mirror images differ; 0 = amplitudes only")

    def __post_init__(self) -> None:
        for key in ("samples", "harmonics", "mirror_terms"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise InputError(f"option {key}: expected an integer, got {v!r}")
        if self.harmonics < 1:
            raise InputError(f"option harmonics: must be >= 1, got {self.harmonics}")
        if self.mirror_terms < 0:
            raise InputError(f"option mirror_terms: must be >= 0, got {self.mirror_terms}")
        need = 2 * max(self.harmonics // 2 + 1, self.harmonics - self.harmonics // 2 + 2,
                       self.mirror_terms + 2) + 1
        if self.samples < need:
            raise InputError(f"option samples: must be at least {need} for harmonics={self.harmonics} "
                             f"and mirror_terms={self.mirror_terms} (Nyquist), got {self.samples}")

    def describe(self, points: np.ndarray) -> np.ndarray:
        return self.describe_many([as_points(points)])[0]

    def describe_many(self, outlines: Sequence[np.ndarray]) -> np.ndarray:
        return fourier_descriptors(outlines, samples=self.samples, harmonics=self.harmonics,
                                   mirror_terms=self.mirror_terms)

    def distance_matrix(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return euclidean_matrix(a, b)


def euclidean_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pairwise Euclidean distances between the rows of a (n, K) and b (m, K): shape (n, m)."""
    a = as_descriptors(a, name="a")
    b = as_descriptors(b, name="b")
    if a.shape[1] != b.shape[1]:
        raise InputError(f"descriptor lengths differ: a has {a.shape[1]}, b has {b.shape[1]}")
    # The direct difference rather than |a|^2 + |b|^2 - 2ab: exact zero on identical rows and no
    # cancellation; K is small, so the (n, m, K) temporary stays cheap for the sizes matched here.
    if a.shape[0] * b.shape[0] * a.shape[1] <= 4_000_000:
        d = a[:, None, :] - b[None, :, :]
        return np.sqrt(np.einsum("ijk,ijk->ij", d, d))
    out = np.empty((a.shape[0], b.shape[0]))
    step = max(1, 4_000_000 // max(1, b.shape[0] * a.shape[1]))
    for i in range(0, a.shape[0], step):
        d = a[i:i + step, None, :] - b[None, :, :]
        out[i:i + step] = np.sqrt(np.einsum("ijk,ijk->ij", d, d))
    return out
