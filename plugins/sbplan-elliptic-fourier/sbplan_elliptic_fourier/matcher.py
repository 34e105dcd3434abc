"""Elliptic Fourier descriptors (Kuhl & Giardina 1982), normalized for rotation, scale and start point.

Kuhl, F. P. and Giardina, C. R. (1982), "Elliptic Fourier features of a closed contour", Computer
Graphics and Image Processing 18, 236-258.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Sequence

import numpy as np

from sbplan.contours import as_points
from sbplan.contracts import DescriptorMatcher, as_descriptors, option
from sbplan.errors import ContourError, InputError

__all__ = ["EllipticFourierMatcher", "elliptic_coefficients", "normalize_coefficients", "elliptic_descriptors"]


def elliptic_coefficients(outlines: Sequence[np.ndarray], *, harmonics: int = 10) -> np.ndarray:
    """Elliptic Fourier coefficients of many closed polygons (Kuhl & Giardina, eqs. 6-9).

    The outline is parametrized by arc length ``t`` in ``[0, T)`` and ``x(t), y(t)`` are expanded as
    ``x(t) = A0 + sum_n a_n cos(2 pi n t / T) + b_n sin(2 pi n t / T)`` and likewise ``y(t)`` with
    ``c_n, d_n``. For a polygon the integrals are exact sums over its edges. Outlines that run
    clockwise as displayed (y down) are read backwards, which negates the sine coefficients
    ``b_n, d_n``; so an outline and its reversed vertex list, or an outer boundary and a hole of
    the same shape, get the same coefficients up to the start point.

    Parameters
    ----------
    outlines : sequence of array_like of shape (N_i, 2)
        Closed outlines ``(x, y)`` in pixels (y down), N_i >= 3, not closed (first point not repeated).
    harmonics : int
        Number of harmonics n = 1..harmonics.

    Returns
    -------
    ndarray of shape (m, harmonics, 4), float64
        ``[a_n, b_n, c_n, d_n]`` per outline and harmonic.

    Raises
    ------
    ContourError
        An outline with fewer than 3 points, non-finite values, or zero length.
    """
    m = len(outlines)
    if m == 0:
        return np.zeros((0, harmonics, 4))
    pts, starts, counts = _pack(outlines)
    nxt = np.arange(1, len(pts) + 1)
    nxt[starts + counts - 1] = starts
    d = pts[nxt] - pts  # edge vectors, each outline closing onto its first point
    dt = np.hypot(d[:, 0], d[:, 1])
    owner = np.repeat(np.arange(m), counts)
    # Cumulative arc length at the end of each edge, restarting per outline.
    cum = np.cumsum(dt)
    before = np.zeros(m)
    before[1:] = cum[starts[1:] - 1]
    t1 = cum - before[owner]
    t0 = t1 - dt
    T = np.add.reduceat(dt, starts)
    if not (T > 0).all():
        bad = int(np.flatnonzero(~(T > 0))[0])
        raise ContourError(f"outlines[{bad}]: zero-length outline, it has no elliptic Fourier descriptor")
    n = np.arange(1, harmonics + 1)
    w = 2 * np.pi * n[None, :] / T[owner][:, None]  # (edges, harmonics)
    dcos = np.cos(w * t1[:, None]) - np.cos(w * t0[:, None])
    dsin = np.sin(w * t1[:, None]) - np.sin(w * t0[:, None])
    # Repeated vertices give zero-length edges: they contribute nothing.
    inv = np.divide(1.0, dt, out=np.zeros_like(dt), where=dt > 0)
    vx, vy = (d[:, 0] * inv)[:, None], (d[:, 1] * inv)[:, None]
    terms = np.stack([vx * dcos, vx * dsin, vy * dcos, vy * dsin], axis=-1)  # (edges, harmonics, 4)
    coeffs = np.add.reduceat(terms, starts, axis=0) * (T[:, None] / (2 * np.pi ** 2 * n[None, :] ** 2))[:, :, None]
    # Shoelace with y down: positive = clockwise as displayed. Tracing an outline backwards from
    # the same start, x(-t) = a cos - b sin: the sine coefficients change sign.
    cross = pts[:, 0] * pts[nxt, 1] - pts[nxt, 0] * pts[:, 1]
    clockwise = np.add.reduceat(cross, starts) > 0
    coeffs[clockwise, :, 1] *= -1
    coeffs[clockwise, :, 3] *= -1
    return coeffs


def _pack(outlines: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All outlines in one (sum N_i, 2) array, with each one's start index and length."""
    try:
        arrays = [np.asarray(p, dtype=np.float64) for p in outlines]
        ok = all(a.ndim == 2 and a.shape[1] == 2 and len(a) >= 3 for a in arrays)
        pts = np.concatenate(arrays) if ok else None
        ok = ok and bool(np.isfinite(pts).all())
    except (TypeError, ValueError):
        ok = False
    if not ok:  # validate one by one: names the first bad outline, accepts OpenCV's (N, 1, 2)
        arrays = [as_points(p, name=f"outlines[{i}]") for i, p in enumerate(outlines)]
        pts = np.concatenate(arrays)
    counts = np.fromiter((len(a) for a in arrays), np.int64, len(arrays))
    starts = np.zeros(len(arrays), np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    return pts, starts, counts


def normalize_coefficients(coeffs: np.ndarray) -> np.ndarray:
    """Kuhl & Giardina's normalization: rotation, scale and start point removed.

    The start point is moved to an end of the first harmonic's ellipse's major axis (eq. 26), the
    outline is rotated so that axis lies along x (eq. 27), and all coefficients are divided by its
    semi-major axis. Afterwards ``a_1 = 1, b_1 = c_1 = 0`` and ``|d_1|`` is the ellipse's axis
    ratio. One ambiguity remains: the other end of the major axis gives the same normalization
    except for the sign of every even harmonic (see :class:`EllipticFourierMatcher`).

    Parameters
    ----------
    coeffs : ndarray of shape (m, H, 4)

    Returns
    -------
    ndarray of shape (m, H, 4)
    """
    a, b, c, d = (coeffs[..., k] for k in range(4))
    a1, b1, c1, d1 = a[:, :1], b[:, :1], c[:, :1], d[:, :1]
    theta = 0.5 * np.arctan2(2 * (a1 * b1 + c1 * d1), a1 ** 2 + c1 ** 2 - b1 ** 2 - d1 ** 2)
    n = np.arange(1, coeffs.shape[1] + 1)[None, :]
    cos, sin = np.cos(n * theta), np.sin(n * theta)
    a2, b2 = a * cos + b * sin, -a * sin + b * cos
    c2, d2 = c * cos + d * sin, -c * sin + d * cos
    psi = np.arctan2(c2[:, :1], a2[:, :1])
    major = np.hypot(a2[:, :1], c2[:, :1])
    if not (major > 0).all():
        bad = int(np.flatnonzero(~(major[:, 0] > 0))[0])
        raise ContourError(f"outlines[{bad}]: degenerate outline (no first harmonic)")
    cp, sp = np.cos(psi) / major, np.sin(psi) / major
    return np.stack([cp * a2 + sp * c2, cp * b2 + sp * d2, -sp * a2 + cp * c2, -sp * b2 + cp * d2], axis=-1)


def elliptic_descriptors(outlines: Sequence[np.ndarray], *, harmonics: int = 10) -> np.ndarray:
    """Normalized elliptic Fourier descriptors of many closed outlines, shape (m, 4 * harmonics).

    The entries are ``a_n, b_n, c_n, d_n`` for n = 1..harmonics after :func:`normalize_coefficients`
    (so the first three are always ``1, 0, 0`` and the fourth is the first ellipse's axis ratio).
    """
    norm = normalize_coefficients(elliptic_coefficients(outlines, harmonics=harmonics))
    return norm.reshape(len(norm), -1)


def _phasors(desc: np.ndarray, harmonics: int) -> tuple[np.ndarray, np.ndarray]:
    """Harmonic n as ``z(t) = P_n exp(i n t) + Q_n exp(-i n t)`` with ``z = x + i y``: (P, Q), (m, H)."""
    c = desc.reshape(len(desc), harmonics, 4)
    a, b, cc, d = c[..., 0], c[..., 1], c[..., 2], c[..., 3]
    return 0.5 * ((a + d) + 1j * (cc - b)), 0.5 * ((a - d) + 1j * (cc + b))


def aligned_distances(a: np.ndarray, b: np.ndarray, harmonics: int, *, samples: int = 0) -> np.ndarray:
    """Euclidean distances between descriptors after the best start point and rotation, shape (n, m).

    ``d(A, B) = min over tau, alpha of || A - R_alpha S_tau B ||``, where ``S_tau`` moves the start
    point by the phase ``tau`` and ``R_alpha`` rotates the outline by ``alpha``. With the phasors of
    :func:`_phasors`, ``||A - R S B||^2 = 2 (|A|^2 + |B|^2 - 2 Re(e^{i alpha} C(tau)))`` where
    ``C(tau) = sum_n conj(PA_n) PB_n e^{i n tau} + conj(QA_n) QB_n e^{-i n tau}``; the best alpha
    (``e^{i alpha} = conj(C) / |C|``) makes the last term ``|C(tau)|``, which is maximized over tau on a grid (an inverse FFT) and
    refined by a parabola through the best grid point and its neighbours.
    """
    pa, qa = _phasors(a, harmonics)
    pb, qb = _phasors(b, harmonics)
    L = samples or max(64, 8 * harmonics)
    n = np.arange(1, harmonics + 1)
    out = np.empty((len(a), len(b)))
    if len(a) == 0 or len(b) == 0:
        return out
    # Bound the (rows, m, L) complex temporaries to a few tens of MB.
    step = max(1, 2_000_000 // max(1, len(b) * L))
    for i in range(0, len(a), step):
        gp = np.conj(pa[i:i + step, None, :]) * pb[None, :, :]  # (r, m, H)
        gq = np.conj(qa[i:i + step, None, :]) * qb[None, :, :]
        spec = np.zeros(gp.shape[:2] + (L,), complex)
        spec[..., n] += gp
        spec[..., L - n] += gq
        c = np.fft.ifft(spec, axis=-1) * L  # C(2 pi j / L)
        mag = np.abs(c)
        j = np.argmax(mag, axis=-1)
        y0 = np.take_along_axis(mag, ((j - 1) % L)[..., None], -1)[..., 0]
        y1 = np.take_along_axis(mag, j[..., None], -1)[..., 0]
        y2 = np.take_along_axis(mag, ((j + 1) % L)[..., None], -1)[..., 0]
        den = y0 - 2 * y1 + y2
        shift = np.divide(0.5 * (y0 - y2), den, out=np.zeros_like(den), where=den < 0)
        best = None
        for tau in (2 * np.pi * j / L, 2 * np.pi * (j + np.clip(shift, -0.5, 0.5)) / L):
            e = np.exp(1j * tau[..., None] * n)
            cval = (gp * e + gq * np.conj(e)).sum(-1)
            rot = np.divide(np.conj(cval), np.abs(cval), out=np.ones_like(cval), where=np.abs(cval) > 0)
            # The residual itself rather than |A|^2 + |B|^2 - 2|C|: exactly zero for equal rows.
            rp = pa[i:i + step, None, :] - rot[..., None] * e * pb[None, :, :]
            rq = qa[i:i + step, None, :] - rot[..., None] * np.conj(e) * qb[None, :, :]
            res = 2 * ((rp.real ** 2 + rp.imag ** 2).sum(-1) + (rq.real ** 2 + rq.imag ** 2).sum(-1))
            best = res if best is None else np.minimum(best, res)
        out[i:i + step] = np.sqrt(best)
    return out


@dataclass(kw_only=True, frozen=True)
class EllipticFourierMatcher(DescriptorMatcher):
    """Elliptic Fourier descriptors (Kuhl & Giardina 1982) with an alignment-aware Euclidean distance.

    Descriptor: the x(t) and y(t) coordinates of the closed polygon, parametrized by arc length, are
    expanded into ``harmonics`` ellipses (``a_n, b_n, c_n, d_n``); the coefficients are normalized
    so that the first ellipse has its major axis along x, unit semi-major axis and its start at the
    end of that axis. That removes translation (the DC term is not used), rotation, scale and start
    point. Unlike the amplitude spectrum of the ``fourier`` matcher it keeps the phases, so it tells
    a shape from its mirror image and from other shapes with the same amplitudes.

    Distance: the Euclidean distance of the coefficient vectors, minimized over the start point and
    the rotation that remain free. Kuhl & Giardina's normalization leaves a two-fold ambiguity
    (either end of the major axis) and is undefined when the first ellipse is a circle (a square,
    a star, any shape with 3-fold or higher rotational symmetry); minimizing over the alignment
    removes both problems. By Parseval, ``d = sqrt(2) * RMS distance`` between the two normalized
    outlines traced in step (truncated to ``harmonics`` harmonics) in units of the first ellipse's
    semi-major axis: d = 0.1 means corresponding outline points are about 7 % of the shape's
    half-length apart, on average. ``default_threshold`` is 0.15 (see the plugin's README for how
    it was chosen); calibration derives its own threshold from the reference image anyway.
    """

    name: ClassVar[str] = "elliptic-fourier"
    description: ClassVar[str] = "normalized elliptic Fourier descriptors (Kuhl & Giardina 1982), aligned Euclidean distance"
    default_threshold: ClassVar[float] = 0.15

    harmonics: int = option(10, "number of elliptic harmonics n = 1..harmonics (descriptor size 4*harmonics)")

    def __post_init__(self) -> None:
        h = self.harmonics
        if isinstance(h, bool) or not isinstance(h, (int, np.integer)):
            raise InputError(f"option harmonics: expected an integer, got {h!r}")
        if not 2 <= h <= 100:
            raise InputError(f"option harmonics: must be between 2 and 100, got {h}")

    def describe(self, points: np.ndarray) -> np.ndarray:
        return self.describe_many([as_points(points)])[0]

    def describe_many(self, outlines: Sequence[np.ndarray]) -> np.ndarray:
        if len(outlines) == 0:
            return np.zeros((0, 4 * self.harmonics))
        return elliptic_descriptors(outlines, harmonics=self.harmonics)

    def distance_matrix(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        a, b = as_descriptors(a, name="a"), as_descriptors(b, name="b")
        k = 4 * self.harmonics
        if a.shape[1] != k or b.shape[1] != k:
            raise InputError(f"descriptor lengths: expected {k} for harmonics={self.harmonics}, "
                             f"got {a.shape[1]} and {b.shape[1]}")
        return aligned_distances(a, b, self.harmonics)
