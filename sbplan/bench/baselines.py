"""What users would pick instead of sbplan for "which floor cells are occupied": the baselines of
``sbplan bench detect``.

Each baseline is set up once from the empty-floor reference image the fixed camera took (the same
one sbplan calibrates on) and then maps a grayscale frame ``(H, W) uint8`` to a ``(rows, cols)``
bool array, True = occupied, ``[row, col]`` with row 0 at the top.

- :class:`ArucoGrid`: the floor carries one ArUco marker per cell (``FloorSpec(layout="aruco")``);
  a cell is free when its marker id is detected near where the reference showed it.
- :class:`AbsDiff`: ``cv2.absdiff`` against the reference, a fixed threshold, a morphological
  opening, and per cell the changed fraction of its footprint.
- :class:`Mog2`: OpenCV's MOG2 trained on the reference and noisy copies of it, then applied with
  learning frozen (``learningRate=0``); same opening and per-cell rule.

Background subtraction judges each cell on its **footprint**: the reference's printed ink within
the symbol's box around the cell centre, dilated by 2 px (the renderer's ground truth calls a cell
occupied when an obstacle covers more than 2 % of the symbol's area, so this is the region that
rule looks at). Cell centres in the image are given (a fixed camera: measured once).

Defaults were tuned on other scenes than the benchmark's (seed 7, conditions clean, noise, shadows,
blur, textured; a sweep of threshold 20/30/40 x fraction 0.01-0.1 for absdiff and varThreshold
16/36/64 x fraction 0.01-0.06 for MOG2, best mean F1): absdiff threshold 30, fraction 0.01;
MOG2 varThreshold 36, fraction 0.01, shadow detection on. ArUco uses OpenCV's default detector
parameters.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import InputError
from ..synth.aruco import marker_dictionary


def _gray(image: np.ndarray, name: str) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim != 2 or image.dtype != np.uint8:
        raise InputError(f"{name}: expected a grayscale (H, W) uint8 image, got {image.shape} {image.dtype}")
    return image


def _centres(centres: np.ndarray) -> np.ndarray:
    centres = np.asarray(centres, dtype=np.float64)
    if centres.ndim != 3 or centres.shape[2] != 2 or not np.isfinite(centres).all():
        raise InputError(f"centres: expected a finite (rows, cols, 2) array of (x, y), got shape {centres.shape}")
    return centres


# -- ArUco marker grid ---------------------------------------------------------------------------
class ArucoGrid:
    """Occupancy from a grid of ArUco markers: a cell whose marker is not found is occupied.

    Parameters
    ----------
    reference : ndarray (H, W) uint8
        The empty marker floor. Every marker's image position is learned from it.
    rows, cols : int
        Grid shape; the marker of cell ``(row, col)`` has id ``row * cols + col``.
    dictionary : str, optional
        ``cv2.aruco`` predefined dictionary name; default the smallest 4x4 dictionary holding
        ``rows * cols`` ids (what :mod:`sbplan.synth.aruco` prints).
    max_offset : float
        A detected id counts only within ``max_offset * pitch`` of its reference position (pitch:
        the median distance between neighbouring reference markers).
    parameters : dict, optional
        ``cv2.aruco.DetectorParameters`` attributes to set (default: OpenCV's defaults).

    Raises
    ------
    InputError
        Bad options, or a reference in which fewer than half the markers are found.
    """

    def __init__(self, reference: np.ndarray, *, rows: int, cols: int, dictionary: str | None = None,
                 max_offset: float = 0.35, parameters: dict | None = None):
        reference = _gray(reference, "reference")
        if int(rows) < 1 or int(cols) < 1:
            raise InputError(f"rows/cols: expected >= 1, got {rows} x {cols}")
        if not 0 < max_offset <= 1:
            raise InputError(f"max_offset: expected a fraction in (0, 1], got {max_offset!r}")
        self.rows, self.cols = int(rows), int(cols)
        if dictionary is None:
            dictionary, d = marker_dictionary(self.rows * self.cols)
        else:
            if not hasattr(cv2.aruco, dictionary):
                raise InputError(f"dictionary: unknown cv2.aruco dictionary {dictionary!r}")
            d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
        self.dictionary = dictionary
        params = cv2.aruco.DetectorParameters()
        for key, value in (parameters or {}).items():
            if not hasattr(params, key):
                raise InputError(f"parameters: cv2.aruco.DetectorParameters has no {key!r}")
            setattr(params, key, value)
        self.parameters = dict(parameters or {})
        self.detector = cv2.aruco.ArucoDetector(d, params)
        ids, centres = self._detect(reference)
        n = self.rows * self.cols
        if len(ids) < n / 2:
            raise InputError(f"reference: only {len(ids)} of {n} ArUco markers found; is it a marker floor?")
        # Cells whose marker the reference misses keep NaN: any position then counts.
        self.expected = np.full((n, 2), np.nan)
        self.expected[ids] = centres
        dist = np.linalg.norm(centres[:, None] - centres[None], axis=2)
        np.fill_diagonal(dist, np.inf)
        pitch = float(np.median(dist.min(axis=1))) if len(centres) > 1 else float(max(reference.shape))
        self.tolerance_px = max_offset * pitch

    def _detect(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        corners, ids, _ = self.detector.detectMarkers(gray)
        if ids is None or len(ids) == 0:
            return np.zeros(0, int), np.zeros((0, 2))
        ids = ids.ravel().astype(int)
        centres = np.array([c.reshape(4, 2).mean(axis=0) for c in corners])
        keep = ids < self.rows * self.cols
        ids, centres = ids[keep], centres[keep]
        # a misread may duplicate an id: keep its first detection
        ids, first = np.unique(ids, return_index=True)
        return ids, centres[first]

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """Occupied cells ``(rows, cols)`` bool of one frame."""
        ids, centres = self._detect(_gray(image, "image"))
        free = np.zeros(self.rows * self.cols, bool)
        if len(ids):
            exp = self.expected[ids]
            off = np.linalg.norm(centres - exp, axis=1)
            free[ids[np.isnan(off) | (off <= self.tolerance_px)]] = True
        return ~free.reshape(self.rows, self.cols)


# -- background subtraction ------------------------------------------------------------------------
def footprints(reference: np.ndarray, centres: np.ndarray, *, box: float, dilate: int = 2
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-cell footprint pixels: the reference's ink inside a ``box``-sided square around each centre.

    Parameters
    ----------
    reference : ndarray (H, W) uint8
    centres : ndarray (rows, cols, 2)
        Cell centres ``(x, y)`` in the image.
    box : float
        Side in pixels of the square searched for ink (the symbol's box).
    dilate : int
        Ink mask grown by this many pixels (blurred edges belong to the symbol too).

    Returns
    -------
    flat : ndarray (K,) int
        Flat indices (``row * W + col``) of footprint pixels.
    cell : ndarray (K,) int
        Cell index ``row * cols + col`` of each.
    counts : ndarray (rows * cols,) int
        Footprint size per cell (at least 1).
    """
    reference = _gray(reference, "reference")
    centres = _centres(centres)
    if not box > 0:
        raise InputError(f"box: expected > 0 pixels, got {box!r}")
    ink = cv2.adaptiveThreshold(reference, 1, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV,
                                2 * int(box) + 1 | 1, 10)
    if dilate > 0:
        ink = cv2.dilate(ink, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * dilate + 1,) * 2))
    h, w = reference.shape
    label = np.full((h, w), -1, np.int32)
    half = box / 2
    for i, (x, y) in enumerate(centres.reshape(-1, 2)):
        x0, x1 = max(int(round(x - half)), 0), min(int(round(x + half)) + 1, w)
        y0, y1 = max(int(round(y - half)), 0), min(int(round(y + half)) + 1, h)
        sub = label[y0:y1, x0:x1]
        sub[(ink[y0:y1, x0:x1] > 0) & (sub < 0)] = i
    flat = np.flatnonzero(label.ravel() >= 0)
    cell = label.ravel()[flat]
    counts = np.maximum(np.bincount(cell, minlength=centres.shape[0] * centres.shape[1]), 1)
    return flat, cell, counts


@dataclass
class _CellVote:
    shape: tuple[int, int]
    flat: np.ndarray
    cell: np.ndarray
    counts: np.ndarray
    fraction: float
    kernel: np.ndarray

    def __call__(self, changed: np.ndarray) -> np.ndarray:
        changed = cv2.morphologyEx(changed, cv2.MORPH_OPEN, self.kernel)
        hits = np.bincount(self.cell, weights=changed.ravel()[self.flat], minlength=len(self.counts))
        return (hits / self.counts > self.fraction).reshape(self.shape)


def _vote(reference, centres, box, fraction, open_px) -> _CellVote:
    if not 0 <= fraction < 1:
        raise InputError(f"fraction: expected a fraction in [0, 1), got {fraction!r}")
    if open_px < 1:
        raise InputError(f"open_px: expected >= 1, got {open_px!r}")
    centres = _centres(centres)
    flat, cell, counts = footprints(reference, centres, box=box)
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (open_px, open_px))
    return _CellVote(centres.shape[:2], flat, cell, counts, fraction, kernel)


class AbsDiff:
    """Background subtraction by absolute difference with the reference.

    Per frame: ``|frame - reference| > threshold``, opening with an ``open_px`` square, and a cell is
    occupied when more than ``fraction`` of its footprint (:func:`footprints`) changed.

    Parameters
    ----------
    reference : ndarray (H, W) uint8
    centres : ndarray (rows, cols, 2)
        Cell centres ``(x, y)`` in the image.
    box : float
        Side of the symbol's box in pixels.
    threshold : int
        Grey-level change that counts (0..255).
    fraction : float
        Changed fraction of a footprint above which its cell is occupied.
    open_px : int
        Side of the opening's square (removes isolated noise pixels).
    """

    def __init__(self, reference: np.ndarray, centres: np.ndarray, *, box: float, threshold: int = 30,
                 fraction: float = 0.01, open_px: int = 3):
        self.reference = _gray(reference, "reference")
        if not 0 <= threshold < 255:
            raise InputError(f"threshold: expected a grey level in [0, 255), got {threshold!r}")
        self.threshold = int(threshold)
        self.vote = _vote(self.reference, centres, box, fraction, open_px)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """Occupied cells ``(rows, cols)`` bool of one frame."""
        diff = cv2.absdiff(_gray(image, "image"), self.reference)
        _, changed = cv2.threshold(diff, self.threshold, 1, cv2.THRESH_BINARY)
        return self.vote(changed)


class Mog2:
    """OpenCV's MOG2 background model, trained on the reference, applied with learning frozen.

    Training: the reference and ``copies`` copies of it with Gaussian noise of ``noise`` grey
    levels (seeded), each with learning; then every frame with ``learningRate=0``. Pixels MOG2
    calls foreground (255; shadows, 127, count as background when ``detect_shadows``) go through
    the same opening and per-cell footprint rule as :class:`AbsDiff`.

    Parameters
    ----------
    reference : ndarray (H, W) uint8
    centres : ndarray (rows, cols, 2)
    box : float
    var_threshold : float
        MOG2's squared Mahalanobis distance threshold.
    detect_shadows : bool
        MOG2's shadow detection (darker, same chromaticity: marked 127, not foreground).
    copies, noise : int, float
        Noisy training copies and their noise sigma.
    fraction, open_px
        As in :class:`AbsDiff`.
    seed : int
        Seed of the training noise.
    """

    def __init__(self, reference: np.ndarray, centres: np.ndarray, *, box: float, var_threshold: float = 36.0,
                 detect_shadows: bool = True, copies: int = 9, noise: float = 3.0, fraction: float = 0.01,
                 open_px: int = 3, seed: int = 0):
        reference = _gray(reference, "reference")
        if copies < 0 or noise < 0 or var_threshold <= 0:
            raise InputError(f"copies/noise/var_threshold: expected copies >= 0, noise >= 0, var_threshold > 0, "
                             f"got {copies}, {noise}, {var_threshold}")
        self.model = cv2.createBackgroundSubtractorMOG2(history=copies + 1, varThreshold=var_threshold,
                                                        detectShadows=detect_shadows)
        rng = np.random.default_rng(seed)
        self.model.apply(reference, learningRate=1.0)
        for k in range(copies):
            noisy = np.clip(reference + rng.normal(0.0, noise, reference.shape), 0, 255).astype(np.uint8)
            self.model.apply(noisy, learningRate=1.0 / (k + 2))
        self.vote = _vote(reference, centres, box, fraction, open_px)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """Occupied cells ``(rows, cols)`` bool of one frame."""
        mask = self.model.apply(_gray(image, "image"), learningRate=0)
        _, changed = cv2.threshold(mask, 200, 1, cv2.THRESH_BINARY)
        return self.vote(changed)
