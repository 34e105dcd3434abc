"""The symbol grid: which lattice cell each symbol centre belongs to.

A grid is ``rows x cols`` cells; cell ``(row, col)`` has row 0 at the top of the image and col 0 at
the left. It is fitted from the symbol centres found in the reference image and keeps:

- ``centres_px``: the measured centre of every cell's symbol, shape (rows, cols, 2), ``(x, y)``;
- ``homography``: the 3x3 projective map from lattice coordinates ``(col, row)`` to pixels, fitted
  to those centres, so a slightly rotated or tilted camera is handled;
- ``tolerance_px``: how far a found symbol's centre may lie from its cell's centre.

The measured centres, not the homography, decide cell membership and cell shapes, so radial lens
distortion (which no homography models) does not move a symbol into the wrong cell.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import CalibrationError

_IDENTITY = np.eye(3)


@dataclass(frozen=True, eq=False)
class Grid:
    rows: int
    cols: int
    centres_px: np.ndarray  # (rows, cols, 2) float64 (x, y)
    homography: np.ndarray  # (3, 3): (col, row, 1) -> pixel (x, y, w)
    tolerance_px: float

    @property
    def shape(self) -> tuple[int, int]:
        return self.rows, self.cols

    @functools.cached_property
    def pitch_px(self) -> tuple[float, float]:
        """Median distance between neighbouring centres along a row (dx) and a column (dy)."""
        c = self.centres_px
        dx = np.linalg.norm(np.diff(c, axis=1), axis=2) if self.cols > 1 else np.zeros(1)
        dy = np.linalg.norm(np.diff(c, axis=0), axis=2) if self.rows > 1 else np.zeros(1)
        dx_m = float(np.median(dx)) if dx.size else 0.0
        dy_m = float(np.median(dy)) if dy.size else 0.0
        return dx_m or dy_m, dy_m or dx_m

    def lattice_to_px(self, col_row: np.ndarray) -> np.ndarray:
        """Map lattice coordinates ``(col, row)`` (N, 2), fractional allowed, to pixels (N, 2)."""
        pts = np.asarray(col_row, dtype=np.float64).reshape(-1, 1, 2)
        return cv2.perspectiveTransform(pts, self.homography).reshape(-1, 2)

    def px_to_lattice(self, xy: np.ndarray) -> np.ndarray:
        """Map pixels ``(x, y)`` (N, 2) to fractional lattice coordinates ``(col, row)`` (N, 2)."""
        pts = np.asarray(xy, dtype=np.float64).reshape(-1, 1, 2)
        return cv2.perspectiveTransform(pts, self.inverse_homography).reshape(-1, 2)

    @functools.cached_property
    def inverse_homography(self) -> np.ndarray:
        """Pixels ``(x, y, 1)`` -> lattice ``(col, row, w)``: the homography's inverse (detection maps
        every frame's symbol centres through it)."""
        return np.linalg.inv(self.homography)

    def assign(self, xy: np.ndarray) -> np.ndarray:
        """The cell ``(row, col)`` each point belongs to, or ``(-1, -1)``.

        A point belongs to a cell when it lies within ``tolerance_px`` of that cell's measured
        centre. Returns an int array of shape (N, 2).
        """
        flat = self.assign_flat(xy)
        out = np.full((len(flat), 2), -1, dtype=np.int64)
        ok = flat >= 0
        out[ok, 0], out[ok, 1] = np.divmod(flat[ok], self.cols)
        return out

    def assign_flat(self, xy: np.ndarray) -> np.ndarray:
        """:meth:`assign` as flat cell indices ``row * cols + col``, -1 for none: shape (N,), int64.

        The nearest lattice position of each point through :attr:`inverse_homography`, kept when the
        point lies within ``tolerance_px`` of that cell's centre; one compiled loop (detection
        assigns a frame's few dozen centres, where numpy's calls cost more than the arithmetic).
        """
        from ._kernels import pair_cells

        xy = np.ascontiguousarray(np.asarray(xy, dtype=np.float64).reshape(-1, 2))
        out = np.empty(len(xy), np.int64)
        if len(xy):
            pair_cells(xy, _IDENTITY, self.inverse_homography, self._flat_centres, self.rows, self.cols,
                       float(self.tolerance_px) ** 2, out)
        return out

    @functools.cached_property
    def _flat_centres(self) -> np.ndarray:
        """The cell centres (rows * cols, 2), C-contiguous, as the compiled loop reads them."""
        return np.ascontiguousarray(self.centres_px.reshape(-1, 2), dtype=np.float64)

    def cell_corners_px(self) -> np.ndarray:
        """Corners of every cell, shape (rows + 1, cols + 1, 2) ``(x, y)``.

        Interior corners are the mean of the four surrounding measured centres; border corners are
        extrapolated by half a cell, so cells follow the true geometry under perspective and lens
        distortion.
        """
        c = self.centres_px
        # pad the centre lattice by one extrapolated ring, then average 2x2 neighbourhoods
        p = np.empty((self.rows + 2, self.cols + 2, 2))
        p[1:-1, 1:-1] = c
        if self.cols > 1:
            p[1:-1, 0] = 2 * c[:, 0] - c[:, 1]
            p[1:-1, -1] = 2 * c[:, -1] - c[:, -2]
        else:
            p[1:-1, 0] = c[:, 0] - [self.pitch_px[0], 0]
            p[1:-1, -1] = c[:, 0] + [self.pitch_px[0], 0]
        if self.rows > 1:
            p[0] = 2 * p[1] - p[2]
            p[-1] = 2 * p[-2] - p[-3]
        else:
            p[0] = p[1] - [0, self.pitch_px[1]]
            p[-1] = p[1] + [0, self.pitch_px[1]]
        return 0.25 * (p[:-1, :-1] + p[1:, :-1] + p[:-1, 1:] + p[1:, 1:])

    def to_json(self) -> dict:
        return {
            "rows": self.rows,
            "cols": self.cols,
            "centres_px": np.round(self.centres_px, 4).tolist(),
            "homography": self.homography.tolist(),
            "tolerance_px": self.tolerance_px,
        }

    @classmethod
    def from_json(cls, data: dict) -> "Grid":
        rows, cols = int(data["rows"]), int(data["cols"])
        centres = np.asarray(data["centres_px"], dtype=np.float64)
        homography = np.asarray(data["homography"], dtype=np.float64)
        if centres.shape != (rows, cols, 2) or homography.shape != (3, 3):
            raise CalibrationError("calibration grid: centres or homography have the wrong shape")
        return cls(rows, cols, centres, homography, float(data["tolerance_px"]))


def size_text(cols: int, rows: int) -> str:
    """A grid's size as people read it, columns first: ``"8 columns × 6 rows"``."""
    return f"{cols} column{'s' if cols != 1 else ''} × {rows} row{'s' if rows != 1 else ''}"


def fit_grid(centres: np.ndarray, *, tolerance: float = 0.3, max_residual: float = 0.25) -> Grid:
    """Fit the symbol grid to symbol centres found in a reference image.

    Parameters
    ----------
    centres : ndarray of shape (N, 2)
        Symbol centres ``(x, y)`` in pixels, in any order.
    tolerance : float
        The assignment tolerance as a fraction of the smaller pitch.
    max_residual : float
        How far (fraction of the smaller pitch) a centre may lie from the fitted homography before
        the grid is called irregular.

    Raises
    ------
    CalibrationError
        Fewer than 4 centres, no lattice structure, a missing or doubled symbol, or a centre far
        off the lattice.
    """
    pts, idx, cols, rows, homography, pitch = _lattice(centres)
    flat = idx[:, 1] * cols + idx[:, 0]
    counts = np.bincount(flat, minlength=rows * cols)
    if (counts > 1).any():
        bad = [(int(k // cols), int(k % cols)) for k in np.flatnonzero(counts > 1)[:5]]
        raise CalibrationError(f"irregular grid: more than one symbol in cell(s) (row, col) {bad}")
    if (counts == 0).any():
        missing = [(int(k // cols), int(k % cols)) for k in np.flatnonzero(counts == 0)[:5]]
        more = "" if (counts == 0).sum() <= 5 else f" and {(counts == 0).sum() - 5} more"
        raise CalibrationError(
            f"irregular grid: a lattice of {size_text(cols, rows)} with no symbol at (row, col) {missing}{more}; "
            "the reference image must show every symbol of a complete grid")
    centres_px = np.empty((rows, cols, 2))
    centres_px[idx[:, 1], idx[:, 0]] = pts
    homography = _fit_homography(idx, pts)
    fitted = cv2.perspectiveTransform(idx.reshape(-1, 1, 2).astype(np.float64), homography).reshape(-1, 2)
    residual = np.linalg.norm(fitted - pts, axis=1)
    if residual.max() > max_residual * pitch:
        k = int(np.argmax(residual))
        raise CalibrationError(
            f"irregular grid: the symbol at (row, col) ({idx[k, 1]}, {idx[k, 0]}) is {residual[k]:.1f} px off the "
            f"fitted lattice (allowed {max_residual * pitch:.1f} px)")
    return Grid(rows, cols, centres_px, homography, float(tolerance * pitch))


def lattice_gaps(centres: np.ndarray) -> np.ndarray:
    """Where the lattice that ``centres`` (N, 2, pixels ``(x, y)``) lie on has a position without
    one, inside the lattice's extent: shape (k, 2), pixels ``(x, y)`` (from the lattice's
    homography), empty when there is no such position or no lattice.

    Calibration looks there for a symbol its first grouping left out (a lens that bends the
    corner symbols more than the others) before :func:`fit_grid` calls the grid irregular.
    """
    try:
        _, idx, cols, rows, homography, _ = _lattice(centres)
    except CalibrationError:
        return np.zeros((0, 2))
    taken = np.zeros((rows, cols), bool)
    taken[idx[:, 1], idx[:, 0]] = True
    row, col = np.nonzero(~taken)
    if not len(row):
        return np.zeros((0, 2))
    at = np.column_stack([col, row]).astype(np.float64).reshape(-1, 1, 2)
    return cv2.perspectiveTransform(at, homography).reshape(-1, 2)


def _lattice(centres: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, int, np.ndarray, float]:
    """The lattice the centres (N, 2) lie on: the centres, each one's lattice index ``(col, row)``
    (N, 2) int64, the lattice's columns and rows, the homography from lattice indices to pixels
    and the smaller pitch. Raises CalibrationError as :func:`fit_grid`."""
    pts = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    n = len(pts)
    if n == 0:
        raise CalibrationError("no symbols found in the reference image")
    if n < 4:
        raise CalibrationError(f"only {n} symbols found in the reference image; a grid needs at least 4")
    # Neighbour displacements give the two lattice directions: take, for every centre, its nearest
    # neighbours and split the vectors into "mostly horizontal" and "mostly vertical".
    d = pts[None, :, :] - pts[:, None, :]
    dist = np.linalg.norm(d, axis=2)
    np.fill_diagonal(dist, np.inf)
    nearest = float(np.median(dist.min(axis=1)))
    if not np.isfinite(nearest) or nearest <= 0:
        raise CalibrationError("symbol centres coincide; cannot fit a grid")
    close = dist < 1.6 * nearest
    vecs = d[close]
    horiz = vecs[(np.abs(vecs[:, 0]) > np.abs(vecs[:, 1])) & (vecs[:, 0] > 0)]
    vert = vecs[(np.abs(vecs[:, 1]) >= np.abs(vecs[:, 0])) & (vecs[:, 1] > 0)]

    def shortest_direction(v: np.ndarray) -> np.ndarray | None:
        if not len(v):
            return None
        lengths = np.linalg.norm(v, axis=1)
        base = v[lengths <= lengths.min() * 1.3]
        return np.median(base, axis=0)

    u, w = shortest_direction(horiz), shortest_direction(vert)
    if u is None:
        if w is None:
            raise CalibrationError("symbol centres form no grid")
        u = np.array([w[1], -w[0]])  # a single column
    if w is None:  # a single row
        w = np.array([-u[1], u[0]])
    basis = np.column_stack([u, w])
    if abs(np.linalg.det(basis)) < 1e-6 * nearest**2:
        raise CalibrationError("symbol centres form no two-dimensional grid")
    origin = pts[np.argmin(pts.sum(axis=1))]
    lat = np.linalg.solve(basis, (pts - origin).T).T
    idx = np.rint(lat)
    # Refine with a homography so perspective does not accumulate rounding errors across the
    # floor; two rounds are enough for a few degrees of tilt.
    homography = None
    for _ in range(3):
        idx -= idx.min(axis=0)
        if len(pts) >= 4 and np.linalg.matrix_rank(np.column_stack([idx, np.ones(n)])) >= 3:
            homography, _ = cv2.findHomography(idx.astype(np.float64), pts, 0)
        if homography is None:
            # collinear lattice (one row or column): an affine map is all there is
            homography = _affine_homography(idx, pts)
        lat = cv2.perspectiveTransform(pts.reshape(-1, 1, 2), np.linalg.inv(homography)).reshape(-1, 2)
        new_idx = np.rint(lat)
        if np.array_equal(new_idx, idx):
            break
        idx = new_idx
    idx -= idx.min(axis=0)
    idx = idx.astype(np.int64)
    cols, rows = int(idx[:, 0].max()) + 1, int(idx[:, 1].max()) + 1
    pitch = min(np.linalg.norm(u), np.linalg.norm(w))
    # (the loop sets one every round: a fitted homography or the affine fallback)
    return pts, idx, cols, rows, np.asarray(homography, np.float64), float(pitch)


def _affine_homography(idx: np.ndarray, pts: np.ndarray) -> np.ndarray:
    a = np.column_stack([idx, np.ones(len(idx))])
    sol, *_ = np.linalg.lstsq(a, pts, rcond=None)
    h = np.eye(3)
    h[:2, :] = sol.T
    if abs(np.linalg.det(h)) < 1e-12:  # single row or column: complete with a perpendicular axis
        axis = h[:2, 0] if np.linalg.norm(h[:2, 0]) > 0 else h[:2, 1]
        perp = np.array([-axis[1], axis[0]])
        if np.linalg.norm(h[:2, 0]) == 0:
            h[:2, 0] = -perp
        else:
            h[:2, 1] = perp
    return h


def _fit_homography(idx: np.ndarray, pts: np.ndarray) -> np.ndarray:
    idx = idx.astype(np.float64)
    if np.linalg.matrix_rank(np.column_stack([idx, np.ones(len(idx))])) >= 3:
        h, _ = cv2.findHomography(idx, pts, 0)
        if h is not None:
            return h
    return _affine_homography(idx, pts)
