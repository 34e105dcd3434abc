"""The outline checks: a found symbol must stay near its cell's reference outline both ways.

Real OpenCV on small synthetic arrays and one rendered scene; behaviour only, never timing.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from sbplan.detection import Detector
from sbplan.detection.calibration import Calibration, calibrate
from sbplan.detection.outline_checks import (INNER_MARGIN_PX, SAMPLES, hidden_and_near, hidden_piece,
                                             inner_tolerance, outline_deviation,
                                             reference_samples, signed_distance_map, signed_distances_to_polygon)
from sbplan.bench.evaluation import condition_scenes

# an L with a thin flag-like tip to the right, as a fixed camera would see one symbol
SYMBOL = np.array([[20, 20], [70, 20], [52, 32], [60, 44], [34, 44], [34, 80], [20, 80]], float)


def _ink(polygon: np.ndarray, shape=(100, 100)) -> np.ndarray:
    ink = np.zeros(shape, np.uint8)
    cv2.fillPoly(ink, [np.rint(polygon * 16).astype(np.int32)], 1, cv2.LINE_8, shift=4)
    return ink.astype(bool)


def _check(found: np.ndarray, *, tolerance: float = 0.5) -> bool:
    points, inward = reference_samples([SYMBOL])
    dmap = signed_distance_map([SYMBOL], (100, 100))
    _, shift = outline_deviation([found], dmap, return_shift=True)
    allowance = np.full((1, SAMPLES), tolerance + INNER_MARGIN_PX)
    return bool(hidden_piece([found], shift, points, inward, allowance, _ink(found))[0])


def test_reference_normals_point_into_the_symbol_whatever_the_orientation():
    for polygon in (SYMBOL, SYMBOL[::-1]):
        points, inward = reference_samples([polygon])
        assert points.shape == inward.shape == (1, SAMPLES, 2)
        np.testing.assert_allclose(np.linalg.norm(inward, axis=-1), 1.0)
        # a small step inward from a point on a straight edge lands inside the symbol
        probe = points[0] + 0.5 * inward[0]
        edge = np.abs(signed_distances_to_polygon(points[0], polygon)) < 1e-9
        assert edge.all()
        assert (signed_distances_to_polygon(probe, polygon) < 0).mean() > 0.9


def test_signed_distance_to_a_polygon():
    square = np.array([[10, 10], [30, 10], [30, 30], [10, 30]], float)
    d = signed_distances_to_polygon(np.array([[20, 20], [20, 12], [35, 20], [20, 5]], float), square)
    np.testing.assert_allclose(d, [-10, -2, 5, 5])


def test_the_whole_symbol_and_a_uniformly_shrunk_one_have_lost_nothing():
    assert not _check(SYMBOL)
    centre = SYMBOL.mean(axis=0)
    # light and focus move the whole outline: a common shift is not a hidden piece
    assert not _check(centre + (SYMBOL - centre) * 0.96)


def test_a_cut_off_tip_is_a_hidden_piece_though_the_outline_stays_near_the_reference():
    # the tip beyond x = 62 is hidden (about 2 % of the symbol): the found outline cuts across it
    clipped = np.array([[20, 20], [62, 20], [56.5, 25], [52, 32], [60, 44], [34, 44], [34, 80], [20, 80]], float)
    dmap = signed_distance_map([SYMBOL], (100, 100))
    # walking the found outline, nothing strays far from *some* reference edge ...
    assert outline_deviation([clipped], dmap)[0] < 3.0
    # ... walking the reference outline finds the missing tip
    assert _check(clipped)


def test_a_hidden_corner_of_the_stem_is_a_hidden_piece():
    clipped = np.array([[20, 20], [70, 20], [52, 32], [60, 44], [34, 44], [34, 74], [28, 80], [20, 80]], float)
    assert _check(clipped)
    # the same corner allowed by a tolerance as large as the cut is accepted
    assert not _check(clipped, tolerance=6.0)


def test_a_symbol_that_passes_within_the_near_band_of_the_limit_is_flagged_near_not_hidden():
    # the stem's bottom 2 px short: hidden under a small allowance, near the limit under a larger
    # one; the whole symbol is neither under that one; a hidden symbol is never also near
    short = np.array([[20, 20], [70, 20], [52, 32], [60, 44], [34, 44], [34, 78], [20, 78]], float)
    points, inward = reference_samples([SYMBOL])
    dmap = signed_distance_map([SYMBOL], (100, 100))

    def flags(found: np.ndarray, tolerance: float) -> tuple[bool, bool]:
        _, shift = outline_deviation([found], dmap, return_shift=True)
        allowance = np.full((1, SAMPLES), tolerance + INNER_MARGIN_PX)
        hidden, near = hidden_and_near([found], shift, points, inward, allowance, _ink(found))
        assert bool(hidden[0]) == bool(hidden_piece([found], shift, points, inward, allowance, _ink(found))[0])
        return bool(hidden[0]), bool(near[0])

    assert flags(short, 0.25) == (True, False)
    assert flags(short, 1.0) == (False, True)
    assert flags(SYMBOL, 1.0) == (False, False)


def test_inner_tolerance_takes_each_points_largest_deviation_and_its_neighbours():
    dev = np.zeros((3, SAMPLES))
    dev[0, 10] = 2.0
    dev[1, 10] = -3.0
    tol = inner_tolerance(dev, np.array([0, 0, 2]), 4)
    assert tol.shape == (4, SAMPLES)
    assert tol[0, 9] == tol[0, 10] == tol[0, 11] == 3.0 and tol[0, 12] == 0.0
    assert (tol[2] == 0).all()
    assert (tol[1] == 3.0).all() and (tol[3] == 3.0).all()  # cells no copy found: the largest tolerance


@pytest.fixture(scope="module")
def bench_sliver():
    """The sliver of `sbplan bench detect` (seed 0, scene index 3): cell (0, 8), 2.3 % of its symbol
    hidden by a bright obstacle, under defocus blur."""
    scenes = list(condition_scenes("blur", scenes=4, size=(1280, 960), grid=(10, 5), seed=0))
    return scenes[0][0], scenes[3][1], scenes[3][2]


def test_a_defocused_symbol_with_a_hidden_corner_is_occupied_and_no_free_one_is(bench_sliver):
    reference, image, truth = bench_sliver
    assert truth.cells[0, 8] == 1 and truth.overlap[0, 8] < 0.025
    cal = calibrate(reference)
    assert cal.inner_tolerance_px.shape == (cal.grid.rows * cal.grid.cols, SAMPLES)
    occupied = Detector(cal)(image).occupied
    assert occupied[0, 8]
    assert not occupied[truth.cells == 0].any()
    assert occupied[truth.cells == 1].all()


def test_calibration_files_without_inner_tolerances_still_load_and_detect(bench_sliver):
    reference, image, truth = bench_sliver
    cal = calibrate(reference)
    data = cal.to_json()
    assert len(data["symbol"]["inner_tolerance_px"]) == cal.grid.rows * cal.grid.cols
    round_trip = Calibration.from_json(data)
    np.testing.assert_allclose(round_trip.inner_tolerance_px, cal.inner_tolerance_px, atol=1e-3)
    del data["symbol"]["inner_tolerance_px"]  # a file written before the inner check existed
    old = Calibration.from_json(data)
    assert old.inner_tolerance_px is None
    occupied = Detector(old)(image).occupied
    assert not occupied[truth.cells == 0].any()


def test_samples_deviation_is_outline_deviation_from_given_samples():
    from sbplan.detection.outline_checks import samples_deviation
    from sbplan.polygons import resample_xy

    square = np.array([[10.0, 10.0], [30.0, 10.0], [30.0, 30.0], [10.0, 30.0]])
    dmap = signed_distance_map([square], (40, 40))
    found = [square + [0.4, -0.3], square * [1.0, 1.05]]
    dev, shift = outline_deviation(found, dmap, return_shift=True)
    x, y = resample_xy(found, SAMPLES)
    dev2, shift2 = samples_deviation(x, y, dmap)
    assert np.allclose(dev, dev2) and np.allclose(shift, shift2)


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 30), s=st.integers(1, 70))
def test_samples_deviation_is_the_rows_median_and_spread(seed, n, s):
    # The compiled median and spread against numpy's, on a distance map's bilinear samples.
    from sbplan.detection.outline_checks import samples_deviation

    rng = np.random.default_rng(seed)
    distance_map = rng.normal(0, 3, (40, 50)).astype(np.float32)
    x, y = rng.uniform(-2, 52, (n, s)), rng.uniform(-2, 42, (n, s))
    dev, shift = samples_deviation(x, y, distance_map)
    d = cv2.remap(distance_map, x.astype(np.float32), y.astype(np.float32), cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_REPLICATE)
    assert np.array_equal(shift, np.median(d, axis=1).astype(np.float32))
    assert np.array_equal(dev, np.abs(d - shift[:, None]).max(axis=1))


@pytest.mark.parametrize("condition", ["shift-8", "drift"])
def test_the_sliver_stays_occupied_when_the_camera_moved(condition):
    # The same 2.3 % sliver as bench_sliver's, after the camera moved (6.4, 4.8) px, or along a drift:
    # the binary outline's pixel phase hides the bite (the reference outline passes the hidden-piece
    # limit by half a pixel), and the grey edge, asked because it came that near, shows the break.
    scenes = list(condition_scenes(condition, scenes=4, size=(1280, 960), grid=(10, 5), seed=0))
    truth = scenes[3][2]
    assert truth.cells[0, 8] == 1 and truth.overlap[0, 8] < 0.025
    occupied = Detector(calibrate(scenes[0][0])).find_cells(scenes[3][1]).occupied
    assert occupied[0, 8]
    assert not occupied[truth.cells == 0].any()
    assert occupied[truth.cells == 1].all()
