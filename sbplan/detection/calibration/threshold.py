"""The match threshold: how far from the reference symbol's descriptor a contour may be and still
be the symbol, derived from measured distances instead of the paper's a-priori 0.5."""

from __future__ import annotations

import numpy as np

from ...contracts import descriptors_of, distances_between


def derive_threshold(symbol_distances: np.ndarray, other_distances: np.ndarray) -> tuple[float, float]:
    """Match threshold from measured distances, and the margin it leaves.

    ``symbol_distances`` are the symbols' distances to the reference descriptor (in the reference
    and in degraded copies of it); ``other_distances`` those of everything that is not a symbol
    (the reference's other contours and the round and rectangular shapes that lighting errors and
    boxes produce). The threshold is twice the farthest symbol, but never beyond halfway to the
    nearest other shape. Returns ``(threshold, margin)``, ``margin = nearest other / farthest
    symbol`` (above 1: they separate).
    """
    d_sym = float(np.max(symbol_distances)) if len(symbol_distances) else 0.0
    d_other = float(np.min(other_distances)) if len(other_distances) else np.inf
    floor = max(d_sym, 1e-6)
    threshold = 2.0 * floor
    if np.isfinite(d_other):
        threshold = min(threshold, d_sym + 0.5 * (d_other - d_sym))
    margin = d_other / floor if np.isfinite(d_other) else float("inf")
    return float(threshold), float(margin)


def confuser_distances(matcher, descriptor: np.ndarray, area: float) -> np.ndarray:
    """Distances from the reference descriptor to shapes a symbol must never be taken for.

    Circles and ellipses (the round contours of lighting errors, the paper's warning) and squares
    and rectangles (boxes, labels), all of the symbol's area.
    """
    t = np.linspace(0, 2 * np.pi, 96, endpoint=False)
    shapes = []
    for aspect in (1.0, 1.3, 1.7, 2.5, 4.0):
        a = np.sqrt(area * aspect / np.pi)
        shapes.append(np.column_stack([a * np.cos(t), a / aspect * np.sin(t)]))
        b = np.sqrt(area * aspect)
        w, h = b / 2, b / aspect / 2
        shapes.append(np.array([[-w, -h], [w, -h], [w, h], [-w, h]]))
    return distances_between(matcher, descriptors_of(matcher, shapes), descriptor[None, :])[:, 0]


def match_threshold(matcher, descriptor: np.ndarray, symbol_distances: np.ndarray,
                    other_distances: np.ndarray, *, area: float) -> tuple[float, float]:
    """The match threshold of ``descriptor`` under ``matcher``, and its margin.

    :func:`derive_threshold` on the symbols' distances against the other shapes' distances and
    the :func:`confuser_distances` of shapes of the symbol's ``area`` (pixels): the one rule both
    :func:`~sbplan.detection.calibration.calibrate` and
    :meth:`~sbplan.detection.calibration.Calibration.matching_for` apply.

    Parameters
    ----------
    matcher : DescriptorMatcher
    descriptor : ndarray of shape (K,)
        The reference symbol's descriptor under ``matcher``.
    symbol_distances, other_distances : ndarray of shape (n,) and (m,)
        Distances to ``descriptor`` of the symbols as seen, and of contours that are not symbols.
    area : float
        The symbol's area in pixels.

    Returns
    -------
    threshold, margin : float
    """
    confusers = confuser_distances(matcher, descriptor, area)
    return derive_threshold(symbol_distances, np.concatenate([np.asarray(other_distances, np.float64), confusers]))
