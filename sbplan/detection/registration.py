"""Per-frame registration: how the camera moved since calibration, from the symbol grid itself.

A ceiling camera vibrates, gets bumped and drifts. Every frame is registered to the calibration
before any cell is decided: the symbols the matcher found in the frame are paired with their
calibrated cells and a transform from calibration pixels to frame pixels is fitted to the pairs.

Pairing. The grid is periodic, so a found symbol is paired with the cell nearest to it after a
coarse estimate (the last frame's movement, or none): that pairing is right while no symbol moved
by half a pitch. The fit is RANSAC over a similarity (shift, rotation, scale; OpenCV's
``estimateAffinePartial2D``, seeded), so that symbols in the wrong place and cells whose symbol an
obstacle hides do not bias it; the pairs are then made again with the fitted transform and the
inliers refitted in closed form (least squares), twice. A homography replaces the similarity where
enough symbols show that it fits clearly better (a camera that tilted).

The one-pitch ambiguity. Moved by a whole pitch, the grid looks the same: the pairing would call it
unmoved. Two things keep that from giving a wrong answer. Movements of more than
:data:`MAX_MOVEMENT_PITCH` of a pitch are refused (the pairing is no longer sure). And among the
transforms a whole pitch apart, the one that puts the most found symbols on cells of the grid is
taken; where another one puts as many there (a whole edge row or column out of sight or hidden), the
floor's own texture between the symbols decides: the calibration keeps a thumbnail of the
reference, and the movement under which the frame's floor correlates best with it is taken (a
movement of a pitch is then refused as too large). Where the texture cannot tell either (a floor
without texture, an old calibration file without the thumbnail) the smaller movement is taken,
since a camera on a mount moves by far less than a pitch between calibration and use, and the
choice is reported (``ambiguous_pitch``).

Limits (documented in docs/operator-guide.md): above :data:`WARN_SHIFT_PX`, :data:`WARN_ROTATION_DEG`
or :data:`WARN_SCALE` the movement is compensated and a warning says so; with fewer than
:data:`MIN_SYMBOLS` symbols paired (unless those few sit where the coarse estimate puts them: a
mostly covered floor), a residual above :data:`MAX_RESIDUAL_PX`, or a movement above
:data:`MAX_MOVEMENT_PITCH` of the pitch, :class:`~sbplan.errors.CameraMotionError` is raised.

Coordinates are pixels ``(x, y)``; transforms are 3x3 matrices acting on ``(x, y, 1)`` that map
calibration pixels to frame pixels.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from ..errors import CameraMotionError
from ..polygons import apply_homography as apply
from ._small import median

if TYPE_CHECKING:
    from .grid import Grid

__all__ = ["CameraMotion", "register", "register_pairs", "refine", "apply", "thumbnail", "grey_centres", "centre_window", "MIN_SYMBOLS", "MAX_RESIDUAL_PX", "MAX_MOVEMENT_PITCH",
           "WARN_SHIFT_PX", "WARN_ROTATION_DEG", "WARN_SCALE"]

#: Fewest symbols paired with cells for a movement to be estimated (a similarity needs two; four
#: leave room for one bad pair to show).
MIN_SYMBOLS = 4
#: The symbols that move together must be at least this share of those paired with cells: an
#: obstacle hides symbols (they are not found) but seldom puts symbol-like shapes near cells.
MIN_INLIER_SHARE = 0.5
#: Largest root-mean-square distance (pixels) between the paired symbols' centres and their cells'
#: moved centres: above it the symbols do not move together (a changed view, another floor).
MAX_RESIDUAL_PX = 1.5
#: Largest movement of any cell centre, as a fraction of the grid's pitch: beyond it a symbol can
#: no longer be paired with its own cell with certainty.
MAX_MOVEMENT_PITCH = 0.25
#: Movements above these are compensated and reported with a warning (recalibrate soon).
WARN_SHIFT_PX = 2.0
WARN_ROTATION_DEG = 0.2
WARN_SCALE = 0.004
#: A symbol's centre is an inlier when it lies this close (pixels) to its cell's moved centre, or
#: RANSAC_PITCH of the pitch when that is more (RANSAC's threshold, then the refits').
INLIER_PX = 1.5
RANSAC_PITCH = 0.02
#: A homography is preferred over the similarity when it lowers the residual below this fraction
#: of the similarity's, on at least HOMOGRAPHY_MIN_SYMBOLS pairs, where the similarity leaves more
#: than HOMOGRAPHY_MIN_RESIDUAL_PX (grey-level centres fit a similarity to ~0.02 px on a camera
#: that did not tilt).
HOMOGRAPHY_GAIN = 0.6
HOMOGRAPHY_MIN_SYMBOLS = 12
HOMOGRAPHY_MIN_RESIDUAL_PX = 0.1
#: The last refit keeps the pairs within TRIM_SIGMAS robust deviations of the median residual
#: (or TRIM_FLOOR_PX, when that is more).
TRIM_SIGMAS = 3.0
TRIM_FLOOR_PX = 0.25
#: Pairing: a centre more than this fraction of a pitch from the nearest cell is not paired.
PAIR_PITCH = 0.4
#: Where the similarity explains the symbols' outline centres no better than this (RMS, pixels),
#: or does not explain enough of them, a homography is tried on the pairs too (a camera that
#: sagged or tilted on its mount since calibration: a tilt of 1 deg moves the corners of a
#: 1280 x 960 view by about 10 px against its centre, which no similarity follows). Outline
#: centres fit a similarity to 0.1-0.3 px where it holds.
HOMOGRAPHY_TRY_PX = 0.5
#: RANSAC is skipped when every pair agrees with the least-squares fit and that fit moves no cell
#: more than this fraction of a pitch from the coarse estimate (pairing again would change nothing).
FAST_PITCH = 0.05


_IDENTITY = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]


@dataclass(frozen=True, eq=False)
class CameraMotion:
    """How the camera moved since calibration, as one frame shows it.

    Attributes
    ----------
    matrix : ndarray of shape (3, 3)
        Calibration pixels ``(x, y, 1)`` -> this frame's pixels.
    shift_px : (float, float)
        Where the image centre of the calibration went, minus where it was: ``(dx, dy)`` pixels.
    rotation_deg : float
        Rotation of the view, counter-clockwise as displayed.
    scale : float
        Size of the view over its size at calibration (> 1: the floor looks larger, camera closer).
    residual_px : float
        Root-mean-square distance between the paired symbols' centres and the moved cell centres.
    symbols_used : int
        Symbols paired with cells and kept by the robust fit (the inliers).
    max_movement_px : float
        Largest movement of any cell centre.
    model : str
        ``"none"`` (identity: nothing estimated), ``"similarity"``, ``"homography"`` or
        ``"assumed"`` (too few symbols to estimate; the coarse estimate was kept because the few
        found sit where it puts them).
    warning : str or None
        Set when the movement exceeds the warning levels, or the estimate was assumed or ambiguous.
    ambiguous_pitch : bool
        Another transform a whole pitch away put as many found symbols on the grid.
    """

    matrix: np.ndarray
    shift_px: tuple[float, float]
    rotation_deg: float
    scale: float
    residual_px: float
    symbols_used: int
    max_movement_px: float
    model: str
    warning: str | None = None
    ambiguous_pitch: bool = False

    @classmethod
    def none(cls) -> "CameraMotion":
        """No movement (registration off)."""
        return cls(np.eye(3), (0.0, 0.0), 0.0, 1.0, 0.0, 0, 0.0, "none")

    @property
    def moved(self) -> bool:
        """True unless the transform is exactly the identity."""
        moved = self.__dict__.get("_moved")
        if moved is None:
            # (asked a dozen times per frame: a list's comparison costs a tenth of np.array_equal's)
            moved = np.asarray(self.matrix, np.float64).ravel().tolist() != _IDENTITY
            object.__setattr__(self, "_moved", moved)
        return moved

    def to_frame(self, xy: np.ndarray) -> np.ndarray:
        """Calibration pixels ``(..., 2)`` -> this frame's pixels."""
        return apply(self.matrix, xy)

    def to_calibration(self, xy: np.ndarray) -> np.ndarray:
        """This frame's pixels ``(..., 2)`` -> calibration pixels."""
        return apply(self._inverse, xy)

    def turn(self, vectors: np.ndarray) -> np.ndarray:
        """Directions ``(..., 2)`` in the calibration's pixels turned as this movement turns them
        (its linear part less the scale; at the image's centre for a homography)."""
        turning = self.__dict__.get("_turning")
        if turning is None:
            turning = np.eye(3)
            turning[:2, :2] = self.matrix[:2, :2] / self.scale
            object.__setattr__(self, "_turning", turning)
        return apply(turning, vectors)

    @property
    def _inverse(self) -> np.ndarray:
        inv = self.__dict__.get("_inv")
        if inv is None:
            inv = np.linalg.inv(self.matrix)
            object.__setattr__(self, "_inv", inv)
        return inv

    def to_json(self) -> dict[str, Any]:
        return {
            "shift_px": [round(self.shift_px[0], 4), round(self.shift_px[1], 4)],
            "rotation_deg": round(self.rotation_deg, 5),
            "scale": round(self.scale, 6),
            "residual_px": round(self.residual_px, 4),
            "symbols_used": self.symbols_used,
            "max_movement_px": round(self.max_movement_px, 4),
            "model": self.model,
            "matrix": np.round(self.matrix, 10).tolist(),
            "warning": self.warning,
            "ambiguous_pitch": self.ambiguous_pitch,
        }

    def summary(self) -> str:
        """One line for people: ``camera: shift (dx, dy) px, rotation r deg, scale s since calibration
        (residual e px, n symbols, model)``."""
        if self.model == "none":
            return "camera: movement not estimated"
        return (f"camera: shift ({signed(self.shift_px[0], 2)}, {signed(self.shift_px[1], 2)}) px, rotation "
                f"{signed(self.rotation_deg, 3)} deg, scale {self.scale:.4f} since calibration "
                f"(residual {self.residual_px:.2f} px, {self.symbols_used} symbols, {self.model})")


def signed(value: float, digits: int) -> str:
    """``value`` with its sign and ``digits`` decimals, a value that rounds to zero as ``+0.00``
    (not ``-0.00``: no movement has a direction).

    Examples
    --------
    >>> signed(-0.0004, 2), signed(-0.25, 1), signed(1.5, 0)
    ('+0.00', '-0.2', '+2')
    """
    return f"{round(float(value), digits) + 0.0:+.{digits}f}"


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise Euclidean distances between (N, 2) arrays."""
    d = a - b
    return np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])


def _pair(centres: np.ndarray, grid: "Grid", to_calibration: np.ndarray, pitch: float) -> np.ndarray:
    """Each centre's nearest cell (flat index; -1 when none lies within PAIR_PITCH of a pitch), the
    centres first mapped to calibration pixels by ``to_calibration`` (one compiled loop:
    :func:`sbplan.detection._kernels.pair_cells`)."""
    out = np.empty(len(centres), np.int64)
    if len(centres):
        _compiled().pair_cells(np.ascontiguousarray(centres, np.float64), np.ascontiguousarray(to_calibration, np.float64),
                               grid.inverse_homography, grid.centres_px.reshape(-1, 2), grid.rows, grid.cols,
                               (PAIR_PITCH * pitch) ** 2, out)
    return out


def _trimmed_fit(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The least-squares similarity of the pairs, refitted without those that stray well beyond the
    others (centres pulled by something dark beside their symbol err by a fraction of a pixel,
    inside RANSAC's threshold). Returns the matrix, the mask of the pairs kept and their RMS.
    (One compiled call, :func:`sbplan.detection._kernels.trimmed_similarity`: it runs twice a frame
    on a few dozen pairs, where a dozen numpy calls cost more than the arithmetic.)"""
    matrix = np.empty((3, 3))
    keep = np.empty(len(src), bool)
    rms = _compiled().trimmed_similarity(np.ascontiguousarray(src, np.float64), np.ascontiguousarray(dst, np.float64),
                                         TRIM_FLOOR_PX, TRIM_SIGMAS, MIN_SYMBOLS, matrix, keep)
    return matrix, keep, float(rms)


def _homography_lsq(src: np.ndarray, dst: np.ndarray) -> np.ndarray | None:
    """The least-squares homography ``dst ~ H src`` (normalised so that ``H[2, 2] = 1``), or None
    when the pairs do not determine one."""
    if len(src) < 4:
        return None
    h, _ = cv2.findHomography(src, dst, 0)
    if h is None or not np.isfinite(h).all() or abs(h[2, 2]) < 1e-12:
        return None
    return h / h[2, 2]


def _trimmed_homography(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """:func:`_trimmed_fit` with a homography: the fit, the mask of the pairs kept and their RMS,
    or None when the pairs do not determine a homography."""
    matrix = _homography_lsq(src, dst)
    if matrix is None:
        return None
    resid = _distances(apply(matrix, src), dst)
    keep = resid <= max(TRIM_FLOOR_PX, TRIM_SIGMAS * 1.4826 * median(resid))
    if HOMOGRAPHY_MIN_SYMBOLS <= int(np.count_nonzero(keep)) < len(keep):
        refit = _homography_lsq(src[keep], dst[keep])
        if refit is not None:
            matrix = refit
            resid = _distances(apply(matrix, src[keep]), dst[keep])
        else:
            keep = np.ones(len(src), bool)
    else:
        keep = np.ones(len(src), bool)
    return matrix, keep, math.sqrt(float(resid @ resid) / len(resid))


def _projective(matrix: np.ndarray) -> bool:
    """Does ``matrix`` (3x3) have a perspective part (a last row other than ``(0, 0, 1)``)?"""
    return bool(matrix[2, 0] or matrix[2, 1])


def register(centres_px: np.ndarray, grid: "Grid", image_shape: tuple[int, int], *,
             hint: np.ndarray | None = None, seed: int = 0, reference_thumbnail: np.ndarray | None = None,
             frame: np.ndarray | None = None) -> CameraMotion:
    """Estimate the camera's movement since calibration from the symbol centres found in a frame:
    :func:`register_pairs`'s movement."""
    return register_pairs(centres_px, grid, image_shape, hint=hint, seed=seed,
                          reference_thumbnail=reference_thumbnail, frame=frame)[0]


def register_pairs(centres_px: np.ndarray, grid: "Grid", image_shape: tuple[int, int], *,
                   hint: np.ndarray | None = None, seed: int = 0, reference_thumbnail: np.ndarray | None = None,
                   frame: np.ndarray | None = None) -> tuple[CameraMotion, np.ndarray]:
    """Estimate the camera's movement since calibration from the symbol centres found in a frame,
    and the cells the symbols that agree with it were paired with.

    Parameters
    ----------
    centres_px : ndarray of shape (N, 2)
        Centres ``(x, y)`` of the outlines the matcher took for symbols, in the frame's pixels.
    grid : Grid
        The calibrated grid (cell centres in calibration pixels).
    image_shape : (H, W)
        The frame's shape (the movement is reported about its centre).
    hint : ndarray (3, 3), optional
        A coarse estimate (calibration -> frame), e.g. the last frame's; default no movement.
    seed : int
        Seed of RANSAC's sampling.
    reference_thumbnail : ndarray, optional
        The calibration's :func:`thumbnail` of the reference; with ``frame`` (the grey frame, (H, W)
        uint8) it decides between movements a whole pitch apart that the symbols cannot tell apart.

    Returns
    -------
    motion : CameraMotion
    cells : ndarray (N,), int
        For each of ``centres_px``, the flat cell index (``row * cols + col``) it was paired with
        as an inlier, or -1 (what :func:`refine` takes).

    Raises
    ------
    CameraMotionError
        Too few symbols to estimate the movement, symbols that do not move together, or a
        movement too large to pair symbols with their cells with certainty.
    """
    centres = np.asarray(centres_px, dtype=np.float64).reshape(-1, 2)
    hint = np.eye(3) if hint is None else np.asarray(hint, dtype=np.float64)
    pitch = float(min(grid.pitch_px))
    ref = grid.centres_px.reshape(-1, 2)
    finite = np.flatnonzero(np.isfinite(centres).all(axis=1))
    centres = centres[finite]
    inlier_px = max(INLIER_PX, RANSAC_PITCH * pitch)

    flat = _pair(centres, grid, np.linalg.inv(hint), pitch)
    paired = flat >= 0
    n_paired = int(paired.sum())
    cells = np.full(len(centres_px), -1, np.int64)
    if n_paired < MIN_SYMBOLS:
        return _few_symbols(centres[paired], ref[flat[paired]], hint, image_shape, pitch, inlier_px,
                            len(centres)), cells
    fast = _agreeing_fit(ref[flat[paired]], centres[paired], hint, inlier_px, pitch)
    if fast is not None:
        # every pair moves together, close to the coarse estimate: nothing for RANSAC to reject,
        # and pairing again with the fit would pair the same cells
        matrix, keep, rms, model = fast
        inliers = np.flatnonzero(paired)[keep]
        return _finish(matrix, rms, inliers, flat, finite, cells, grid, image_shape, pitch,
                       reference_thumbnail, frame, model)
    need = max(MIN_SYMBOLS, MIN_INLIER_SHARE * n_paired)
    cv2.setRNGSeed(int(seed))
    m2, _ = cv2.estimateAffinePartial2D(ref[flat[paired]], centres[paired], method=cv2.RANSAC,
                                        ransacReprojThreshold=inlier_px, maxIters=500, confidence=0.999,
                                        refineIters=0)
    best = None  # (matrix, rms, inliers, flat, model)
    found = 0
    if m2 is not None:
        # pair again with the fitted movement (a centre near half a pitch from the hint's cell finds
        # its own), keep the inliers and refit them in closed form
        matrix = np.vstack([m2, [0.0, 0.0, 1.0]])
        flat_s, inliers = _inliers(matrix, centres, grid, ref, pitch, inlier_px)
        found = len(inliers)
        if len(inliers) >= need:
            matrix, keep, rms = _trimmed_fit(ref[flat_s[inliers]], centres[inliers])
            best = (matrix, rms, inliers[keep], flat_s, "similarity")
    if best is None or best[1] > HOMOGRAPHY_TRY_PX:
        # a camera that tilted since calibration: no similarity follows the whole view
        tilted = _homography_pairs(ref[flat[paired]], centres[paired], centres, grid, ref, pitch, inlier_px, seed)
        if tilted is not None:
            matrix, rms, inliers, flat_h = tilted
            found = max(found, len(inliers))
            if len(inliers) >= need and (best is None or (len(inliers) >= len(best[2])
                                                          and rms < HOMOGRAPHY_GAIN * best[1])):
                best = (matrix, rms, inliers, flat_h, "homography")
    if best is None:
        if m2 is None and not found:
            raise CameraMotionError(f"cannot estimate the camera's movement: the {n_paired} symbols found do not "
                                    f"move together; recalibrate on the empty floor (sbplan calibrate)")
        raise CameraMotionError(f"cannot estimate the camera's movement: only {found} of the {n_paired} "
                                f"symbols found near their cells move together; the view changed or the calibration "
                                f"is another camera's or floor's; recalibrate on the empty floor (sbplan calibrate)")
    matrix, rms, inliers, flat, model = best
    return _finish(matrix, rms, inliers, flat, finite, cells, grid, image_shape, pitch,
                   reference_thumbnail, frame, model)


def _inliers(matrix: np.ndarray, centres: np.ndarray, grid: "Grid", ref: np.ndarray, pitch: float,
             inlier_px: float) -> tuple[np.ndarray, np.ndarray]:
    """The centres paired again under ``matrix`` (each one's cell, -1 for none) and the indices of
    those within ``inlier_px`` of their cell's moved centre."""
    flat = _pair(centres, grid, np.linalg.inv(matrix), pitch)
    ok = np.flatnonzero(flat >= 0)
    resid = _distances(apply(matrix, ref[flat[ok]]), centres[ok])
    return flat, ok[resid <= inlier_px]


def _homography_pairs(src: np.ndarray, dst: np.ndarray, centres: np.ndarray, grid: "Grid", ref: np.ndarray,
                      pitch: float, inlier_px: float, seed: int
                      ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray] | None:
    """A homography fitted robustly to the pairs ``src`` -> ``dst`` (RANSAC, seeded), the centres
    paired again with it and its inliers refitted (trimmed least squares): the matrix, the RMS,
    the inliers (indices of ``centres``) and the pairing; None with fewer than
    :data:`HOMOGRAPHY_MIN_SYMBOLS` pairs or no fit."""
    if len(src) < HOMOGRAPHY_MIN_SYMBOLS:
        return None
    cv2.setRNGSeed(int(seed))
    h, _ = cv2.findHomography(src, dst, cv2.RANSAC, inlier_px, maxIters=500, confidence=0.999)
    if h is None or not np.isfinite(h).all() or abs(h[2, 2]) < 1e-12:
        return None
    flat, inliers = _inliers(h / h[2, 2], centres, grid, ref, pitch, inlier_px)
    if len(inliers) < HOMOGRAPHY_MIN_SYMBOLS:
        return None
    fit = _trimmed_homography(ref[flat[inliers]], centres[inliers])
    if fit is None:
        return None
    matrix, keep, rms = fit
    return matrix, rms, inliers[keep], flat


def _agreeing_fit(src: np.ndarray, dst: np.ndarray, hint: np.ndarray, inlier_px: float,
                  pitch: float) -> tuple[np.ndarray, np.ndarray, float, str] | None:
    """The trimmed least-squares fit of the pairs when all of them agree with it within
    ``inlier_px``, it lies within :data:`FAST_PITCH` of a pitch of ``hint`` everywhere and, a
    similarity, it leaves at most :data:`HOMOGRAPHY_TRY_PX`; else None (RANSAC's path must sort
    the pairs, and try a homography): the matrix, the mask of the pairs kept, their RMS and the
    model. The fit is a similarity, or a homography when ``hint`` is one (a tilted camera's last
    pose). A camera that moves little between frames takes this path: one symbol in a wrong place
    lies far off any fit and sends the frame to RANSAC."""
    fit: tuple[np.ndarray, np.ndarray, float] | None
    model = "similarity"
    if _projective(hint) and len(src) >= HOMOGRAPHY_MIN_SYMBOLS:
        fit, model = _trimmed_homography(src, dst), "homography"
    else:
        fit = _trimmed_fit(src, dst)
    if fit is None:
        return None
    matrix, keep, rms = fit
    moved = apply(matrix, src)
    if float(_distances(moved, dst).max()) > inlier_px:
        return None
    if float(np.abs(moved - apply(hint, src)).max()) > FAST_PITCH * pitch:
        return None
    if model == "similarity" and rms > HOMOGRAPHY_TRY_PX:
        # no similarity follows these symbols (a camera that tilted): RANSAC's path tries a
        # homography (a large pitch's threshold lets a tilted view's pairs all "agree")
        return None
    return matrix, keep, rms, model


def _finish(matrix: np.ndarray, rms: float, inliers: np.ndarray, flat: np.ndarray, finite: np.ndarray,
            cells: np.ndarray, grid: "Grid", image_shape, pitch: float, reference_thumbnail, frame,
            model: str = "similarity") -> tuple[CameraMotion, np.ndarray]:
    """register_pairs' last steps: the whole-pitch ambiguity resolved, the motion checked against
    the limits, the inliers' cells recorded."""
    matrix, ambiguous = _resolve_pitch(matrix, _pitch_ambiguity(flat[inliers], grid), grid,
                                       reference_thumbnail, frame)
    # (a movement a whole pitch away that the texture chose is refused here as too large)
    motion = _motion(matrix, rms, len(inliers), model, image_shape, grid, pitch, ambiguous)
    cells[finite[inliers]] = flat[inliers]
    return motion, cells


def refine(centres_px: np.ndarray, cells: np.ndarray, cell_centres_px: np.ndarray, grid: "Grid",
           image_shape: tuple[int, int], coarse: CameraMotion) -> CameraMotion:
    """The movement refitted on precise centres of symbols already paired with their cells.

    Parameters
    ----------
    centres_px : ndarray (N, 2)
        Sub-pixel centres of symbols in the frame (:func:`grey_centres`); NaN rows are left out.
    cells : ndarray (N,), int
        Each one's flat cell index (from :func:`register_pairs`).
    cell_centres_px : ndarray (rows * cols, 2)
        The same kind of centre measured on the reference (the calibration's registration centres).
    grid : Grid
    image_shape : (H, W)
    coarse : CameraMotion
        What :func:`register` found; kept where too few centres are usable, and its whole-pitch
        ambiguity carried over.

    Returns
    -------
    CameraMotion
        A homography where at least HOMOGRAPHY_MIN_SYMBOLS pairs show it fits clearly better
        than the similarity (a camera that tilted), else the similarity.
    """
    ok = np.isfinite(centres_px).all(axis=1) & (cells >= 0)
    if ok.sum() < MIN_SYMBOLS:
        return coarse
    src, dst = cell_centres_px[cells[ok]], centres_px[ok]
    # A grey-level centre reads everything dark in its window: an object's edge there pulls it
    # off its symbol by pixels (a dark disc beside a free symbol: 2-14 px). The outlines' movement
    # placed every one of these symbols within a fraction of a pixel; a centre it does not place
    # as near as the others (INLIER_PX, or TRIM_SIGMAS robust deviations when they scatter more)
    # is left out before any fit (with the few symbols a mostly covered floor shows, one such
    # centre drags a least-squares fit past every trimming: the frame was refused).
    pitch = float(min(grid.pitch_px))
    off = _distances(apply(coarse.matrix, src), dst)
    near = off <= min(max(INLIER_PX, TRIM_SIGMAS * 1.4826 * median(off)), RANSAC_PITCH * pitch + INLIER_PX)
    if near.sum() < MIN_SYMBOLS:
        return coarse
    src, dst = src[near], dst[near]
    tilted = _trimmed_homography(src, dst) if coarse.model == "homography" else None
    if tilted is not None:
        # (the outlines already showed a view no similarity follows: its trimming would drop the
        # corners that show it)
        matrix, keep, rms = tilted
        model = "homography"
    else:
        matrix, keep, rms = _trimmed_fit(src, dst)
        model = "similarity"
    if model == "similarity" and keep.sum() >= HOMOGRAPHY_MIN_SYMBOLS and rms > HOMOGRAPHY_MIN_RESIDUAL_PX:
        h = _homography_lsq(src[keep], dst[keep])
        if h is not None:
            rms_h = float(np.sqrt(np.mean(np.sum((apply(h, src[keep]) - dst[keep]) ** 2, axis=1))))
            if rms_h < HOMOGRAPHY_GAIN * rms:
                matrix, rms, model = h, rms_h, "homography"
    motion = _motion(matrix, rms, int(keep.sum()), model, image_shape, grid, pitch, coarse.ambiguous_pitch)
    if coarse.warning and coarse.ambiguous_pitch and motion.warning != coarse.warning:
        object.__setattr__(motion, "warning", coarse.warning if motion.warning is None
                           else f"{motion.warning}; {coarse.warning.split('; ')[-1]}")
    return motion


def _few_symbols(found: np.ndarray, cells: np.ndarray, hint: np.ndarray, image_shape, pitch: float,
                 inlier_px: float, n_found: int) -> CameraMotion:
    """Fewer than MIN_SYMBOLS paired: a mostly covered floor when the few sit where the coarse
    estimate puts them (then that estimate stands), else nothing can be said."""
    if len(found):
        resid = np.linalg.norm(apply(hint, cells) - found, axis=1)
        if (resid <= inlier_px).all():
            rms = float(np.sqrt(np.mean(resid ** 2)))
            motion = _motion(hint, rms, len(found), "assumed", image_shape, None, pitch, False)
            warning = (f"only {len(found)} symbol{'s' if len(found) != 1 else ''} visible: the floor is mostly "
                       f"covered; the camera is assumed not to have moved since the last estimate")
            return dataclasses.replace(motion, warning=warning)
    if n_found >= MIN_SYMBOLS:
        raise CameraMotionError(
            f"camera moved since calibration: {n_found} symbols found but only {len(found)} near a cell of the "
            f"grid; a movement of more than {MAX_MOVEMENT_PITCH:g} of the grid's {pitch:.0f} px pitch cannot be "
            f"compensated; recalibrate with 'sbplan calibrate REFERENCE.png' on the empty floor")
    raise CameraMotionError(
        f"cannot estimate the camera's movement: {n_found} symbol{'s' if n_found != 1 else ''} found "
        f"(at least {MIN_SYMBOLS} needed); the view changed, the camera failed, the floor is covered or the "
        f"calibration is another floor's; "
        f"recalibrate on the empty floor (sbplan calibrate)")


def _pitch_ambiguity(cells: np.ndarray, grid: "Grid") -> list[tuple[int, int]]:
    """The pairings a whole pitch away, ``(d_row, d_col)``, that would put as many of the inlier
    symbols on the grid: the symbols alone cannot tell those movements from the one found."""
    row, col = np.divmod(cells, grid.cols)
    n = len(cells)
    if not n:
        return []
    # every inlier stays on the grid shifted by (dr, dc) when the extreme ones do
    r0, r1, c0, c1 = int(row.min()), int(row.max()), int(col.min()), int(col.max())
    return [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1)
            if (dr or dc) and r0 + dr >= 0 and r1 + dr < grid.rows and c0 + dc >= 0 and c1 + dc < grid.cols]


#: The reference thumbnail is the reference image made this many times smaller.
THUMBNAIL_FACTOR = 4
#: The floor's texture decides between movements a pitch apart when the best one's correlation
#: beats the next one's by this much; below it the smaller movement is kept, with a warning.
THUMBNAIL_MARGIN = 0.1


def thumbnail(gray: np.ndarray) -> np.ndarray:
    """The grey image made :data:`THUMBNAIL_FACTOR` times smaller (area average): what calibration
    keeps of the reference to tell movements a pitch apart by the floor's own texture."""
    h, w = gray.shape
    small = _reduced(gray, (max(1, h // THUMBNAIL_FACTOR), max(1, w // THUMBNAIL_FACTOR)))
    return np.clip(np.rint(small), 0, 255).astype(np.uint8)


def _reduced(gray: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``gray`` reduced to ``shape`` (H, W) by area averaging, by halvings while it is at least
    twice as large (OpenCV halves about ten times faster than it reduces by 4 at once), in float32
    (rounding between halvings would blur the floor's faint texture). Returns float32."""
    gray = gray.astype(np.float32)
    while gray.shape[0] >= 2 * shape[0] and gray.shape[1] >= 2 * shape[1] \
            and gray.shape[0] % 2 == 0 and gray.shape[1] % 2 == 0:
        gray = cv2.resize(gray, (gray.shape[1] // 2, gray.shape[0] // 2), interpolation=cv2.INTER_AREA)
    if gray.shape != tuple(shape):
        gray = cv2.resize(gray, (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
    return gray


def _texture(img: np.ndarray) -> np.ndarray:
    """The floor's texture: the image less its local mean (light changes slowly, texture does not)."""
    img = img.astype(np.float32)
    return img - cv2.blur(img, (9, 9), borderType=cv2.BORDER_REFLECT)


def _view_scores(reference_thumb: np.ndarray, frame: np.ndarray, matrices: list[np.ndarray]) -> list[float]:
    """How well the frame's floor texture matches the reference's moved by each matrix (normalized
    correlation over the floor between symbols, on thumbnails)."""
    f = THUMBNAIL_FACTOR
    th, tw = reference_thumb.shape
    small = _reduced(frame, (th, tw))
    tex = _texture(small)
    # the floor between the symbols: the printed grid looks the same a pitch away, its floor does not
    ref = reference_thumb.astype(np.float32)
    floor = cv2.erode((ref > np.percentile(ref, 40)).astype(np.uint8), np.ones((5, 5), np.uint8))
    s = np.diag([1.0 / f, 1.0 / f, 1.0])
    scores = []
    for m in matrices:
        mt = s @ m @ np.linalg.inv(s)
        warped = cv2.warpPerspective(_texture(reference_thumb), mt, (tw, th), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
        mask = cv2.warpPerspective(floor, mt, (tw, th), flags=cv2.INTER_NEAREST) > 0
        mask &= np.isfinite(warped)
        if mask.sum() < 50:
            scores.append(-1.0)
            continue
        a, b = tex[mask], warped[mask]
        a, b = a - a.mean(), b - b.mean()
        scores.append(float(np.dot(a, b) / max(np.sqrt(np.dot(a, a) * np.dot(b, b)), 1e-6)))
    return scores


def _resolve_pitch(matrix: np.ndarray, ambiguous: list[tuple[int, int]], grid: "Grid",
                   reference_thumb: np.ndarray | None, frame: np.ndarray | None) -> tuple[np.ndarray, bool]:
    """Choose between ``matrix`` and the movements a whole pitch away that the symbols cannot tell
    apart, by the floor's texture (needs the calibration's reference thumbnail and the frame).
    Returns the chosen matrix and whether the choice stays ambiguous."""
    if not ambiguous or reference_thumb is None or frame is None:
        return matrix, bool(ambiguous)
    # a whole pitch of the lattice, as calibration pixels
    c = grid.centres_px
    step_col = np.median(np.diff(c, axis=1).reshape(-1, 2), axis=0) if grid.cols > 1 else np.zeros(2)
    step_row = np.median(np.diff(c, axis=0).reshape(-1, 2), axis=0) if grid.rows > 1 else np.zeros(2)
    candidates = [matrix]
    for dr, dc in ambiguous:
        t = np.eye(3)
        # pairing each symbol with the cell (dr, dc) away moves the calibration's view back by that
        t[:2, 2] = -(dr * step_row + dc * step_col)
        candidates.append(matrix @ t)
    scores = _view_scores(reference_thumb, frame, candidates)
    order = np.argsort(scores)[::-1]
    best, second = int(order[0]), int(order[1])
    if scores[best] - scores[second] < THUMBNAIL_MARGIN:
        return matrix, True
    return candidates[best], False


def movement_at_centre(matrix: np.ndarray, image_shape: tuple[int, int]) -> tuple[tuple[float, float], float, float]:
    """What a movement ``matrix`` (3x3, calibration -> frame pixels) does at the image's centre:
    the centre's shift ``(dx, dy)`` (pixels), the rotation (degrees) and the scale of the local
    linear part there. Exact for a similarity; for a homography (a camera that tilted), the
    movement an operator sees in the middle of the picture.

    Examples
    --------
    >>> import numpy as np
    >>> movement_at_centre(np.array([[1.0, 0, 2.5], [0, 1.0, -1.0], [0, 0, 1]]), (101, 201))
    ((2.5, -1.0), 0.0, 1.0)
    """
    h, w = int(image_shape[0]), int(image_shape[1])
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    # the centre and a pixel to its right and below it, moved: the local linear part at the centre
    # (three points in plain floats: numpy's calls would cost more than the arithmetic, twice a frame)
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = np.asarray(matrix, np.float64).tolist()

    def moved(x: float, y: float) -> tuple[float, float]:
        d = m20 * x + m21 * y + m22
        return (m00 * x + m01 * y + m02) / d, (m10 * x + m11 * y + m12) / d

    (mx, my), (ax, ay), (bx, by) = moved(cx, cy), moved(cx + 1.0, cy), moved(cx, cy + 1.0)
    l00, l10, l01, l11 = ax - mx, ay - my, bx - mx, by - my
    rotation = math.degrees(math.atan2(l01 - l10, l00 + l11))
    scale = math.sqrt(abs(l00 * l11 - l01 * l10))
    return (mx - cx, my - cy), rotation, scale


def _motion(matrix: np.ndarray, rms: float, used: int, model: str, image_shape, grid: "Grid | None", pitch: float,
            ambiguous: bool) -> CameraMotion:
    shift, rotation, scale = movement_at_centre(matrix, image_shape)
    if grid is not None:
        movement = float(_compiled().largest_shift(np.ascontiguousarray(matrix, np.float64), grid._flat_centres))
    else:
        movement = float(math.hypot(*shift))
    if rms > MAX_RESIDUAL_PX:
        raise CameraMotionError(
            f"cannot trust the camera's movement: the {used} symbols found fit it only within {rms:.2f} px "
            f"(at most {MAX_RESIDUAL_PX} px); the view changed or the calibration is another camera's or floor's; "
            f"recalibrate on the empty floor (sbplan calibrate)")
    if movement > MAX_MOVEMENT_PITCH * pitch:
        raise CameraMotionError(
            f"camera moved by {movement:.1f} px since calibration (shift ({shift[0]:+.1f}, {shift[1]:+.1f}) px, "
            f"rotation {rotation:+.2f} deg, scale {scale:.3f}): more than {MAX_MOVEMENT_PITCH:g} of the grid's "
            f"{pitch:.0f} px pitch, too far to pair symbols with their cells with certainty; recalibrate with "
            f"'sbplan calibrate REFERENCE.png' on the empty floor")
    warning = None
    if math.hypot(*shift) > WARN_SHIFT_PX or abs(rotation) > WARN_ROTATION_DEG or abs(scale - 1) > WARN_SCALE:
        warning = (f"camera moved since calibration (shift ({shift[0]:+.1f}, {shift[1]:+.1f}) px, rotation "
                   f"{rotation:+.2f} deg, scale {scale:.4f}); detection compensated it; re-anchor the calibration "
                   f"with 'sbplan calibrate --update CALIBRATION.json FRAME.png'")
    if ambiguous:
        note = ("a whole edge row or column of symbols is hidden and the floor's texture cannot tell: a "
                "movement of a whole pitch would fit the symbols as well; the smaller movement was taken")
        warning = note if warning is None else f"{warning}; {note}"
    return CameraMotion(matrix, shift, rotation, scale, rms, used, movement, model, warning, ambiguous)


#: Pixels of floor kept around a symbol's bounding box when its grey-level centre is measured
#: (a defocused symbol's edge reaches 3 px into its floor: its window's border must be floor;
#: with 3, the suite's blur moved the registration by 0.17-0.20 px, with 5 by 0.08).
CENTRE_MARGIN_PX = 5
#: How far below the floor's level, as a share of it, ink starts to weigh at the least (keeps the
#: floor's grain out of the centre): 10 grey levels on a floor of 200. A share, not grey levels:
#: under the suite's low light (a floor near 50) a fixed 10 kept the ink's blurred rim out and moved
#: a 4K frame's registration by 0.2 px (now 0.06).
CENTRE_FLOOR_SHARE = 0.05


def centre_window(polygons) -> int:
    """The side of the square :func:`grey_centres` reads around symbols whose outlines are
    ``polygons``: the largest extent plus the margin on both sides. Calibration and detection
    use the same side, so that the floor read around a symbol weighs the same in both."""
    extent = max(float(np.ptp(np.asarray(p, np.float64), axis=0).max()) for p in polygons)
    return int(np.ceil(extent)) + 2 * CENTRE_MARGIN_PX + 1


def grey_centres(gray: np.ndarray, boxes: np.ndarray, side: int) -> np.ndarray:
    """Sub-pixel centres of dark symbols: the centre of darkness inside each box.

    A square of ``side`` pixels (:func:`centre_window`) centred on each box is read from the grey image;
    the floor's level is a plane through the means of the square's four sides, and every pixel
    weighs by how much darker than the plane it is, less an allowance for the floor's grain (three
    standard deviations of the border about the plane, at least :data:`CENTRE_FLOOR_SHARE` of the
    floor's level), relative to the plane (light multiplies). Antialiased edges weigh in part, so the
    centre follows sub-pixel movements that the binary outline's pixels cannot show (a polygon's
    centre of area errs by 0.1 to 0.3 px, the same way on every symbol of a regular grid; this by
    about 0.05 px). Each square is read once, by a compiled loop
    (:func:`sbplan.detection._kernels.grey_centres`).

    Parameters
    ----------
    gray : ndarray of shape (H, W), uint8
    boxes : ndarray of shape (N, 4)
        ``(x0, y0, x1, y1)`` pixel bounds (inclusive) of each symbol.
    side : int
        The square's side (the same for the reference and every frame).

    Returns
    -------
    ndarray of shape (N, 2), float64 ``(x, y)``; NaN for a box that leaves the image.
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    out = np.full((len(boxes), 2), np.nan)
    if not len(boxes):
        return out
    gray = np.ascontiguousarray(gray, dtype=np.uint8)
    h, w = gray.shape
    finite = np.isfinite(boxes).all(axis=1)
    mid = np.rint((boxes[:, :2] + boxes[:, 2:]) / 2)
    mid[~finite] = -side
    corner = mid.astype(np.int64) - side // 2
    inside = (corner[:, 0] >= 0) & (corner[:, 1] >= 0) & (corner[:, 0] + side <= w) & (corner[:, 1] + side <= h)
    if inside.all():
        _compiled().grey_centres(gray, corner, int(side), CENTRE_FLOOR_SHARE, out)
    elif inside.any():
        res = np.empty((int(inside.sum()), 2))
        _compiled().grey_centres(gray, np.ascontiguousarray(corner[inside]), int(side), CENTRE_FLOOR_SHARE, res)
        out[inside] = res
    return out


@functools.cache
def _compiled():
    """The compiled kernels, imported on first use (see :mod:`sbplan.detection._kernels`)."""
    from . import _kernels
    return _kernels
