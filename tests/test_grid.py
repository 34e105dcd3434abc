"""Grid fitting: regular, rotated and tilted lattices; clear errors for irregular ones."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sbplan.errors import CalibrationError
from sbplan.detection.grid import fit_grid, lattice_gaps

PAPER_X = [47, 146, 247, 346, 445, 544, 644, 744]
PAPER_Y = [45, 138, 229, 322, 413, 506]


def lattice(cols, rows, homography):
    cr = np.array([(c, r) for r in range(rows) for c in range(cols)], np.float64)
    return cr, cv2.perspectiveTransform(cr.reshape(-1, 1, 2), homography).reshape(-1, 2)


def test_paper_figure_6_centres():
    pts = np.array([(x, y) for y in PAPER_Y for x in PAPER_X], np.float64)
    grid = fit_grid(np.random.default_rng(3).permutation(pts))
    assert (grid.rows, grid.cols) == (6, 8)
    assert grid.centres_px[0, 0].tolist() == [47, 45] and grid.centres_px[5, 7].tolist() == [744, 506]
    assert grid.assign(np.array([[146.0, 138.0], [300.0, 290.0]])).tolist() == [[1, 1], [-1, -1]]


@pytest.mark.parametrize("angle_deg, tilt", [(0.0, 0.0), (4.0, 0.0), (-3.0, 3e-4), (2.0, -4e-4)])
def test_rotated_and_tilted_grids(angle_deg, tilt):
    a = np.radians(angle_deg)
    h = np.array([[60 * np.cos(a), -55 * np.sin(a), 100], [60 * np.sin(a), 55 * np.cos(a), 80], [tilt, tilt / 2, 1]])
    cr, pts = lattice(12, 9, h)
    grid = fit_grid(pts[::-1])
    assert (grid.rows, grid.cols) == (9, 12)
    cells = grid.assign(pts + 2.0)  # slightly off-centre points still land in their own cells
    assert cells[:, ::-1].tolist() == cr.astype(int).tolist()
    corners = grid.cell_corners_px()
    assert corners.shape == (10, 13, 2)


def test_irregular_grids_are_refused_with_the_cell_named():
    pts = np.array([(x, y) for y in PAPER_Y for x in PAPER_X], np.float64)
    with pytest.raises(CalibrationError, match=r"no symbol at \(row, col\) \[\(2, 3\)\]"):
        fit_grid(np.delete(pts, 2 * 8 + 3, axis=0))
    shifted = pts.copy()
    shifted[10] += [35, 0]
    with pytest.raises(CalibrationError, match="irregular grid"):
        fit_grid(shifted)
    with pytest.raises(CalibrationError, match="no symbols"):
        fit_grid(np.zeros((0, 2)))
    with pytest.raises(CalibrationError, match="at least 4"):
        fit_grid(pts[:3])


def test_lattice_gaps_are_the_empty_positions_inside_the_lattice():
    pts = np.array([(x, y) for y in PAPER_Y for x in PAPER_X], np.float64)
    assert lattice_gaps(pts).shape == (0, 2)
    gaps = lattice_gaps(np.delete(pts, [2 * 8 + 3, 5 * 8 + 7], axis=0))
    assert sorted(np.rint(gaps).astype(int).tolist()) == [[346, 229], [744, 506]]
    assert lattice_gaps(pts[:3]).shape == (0, 2)  # no lattice to speak of
