"""Row bands (sbplan.detection.bands) and the detection that uses them."""

from __future__ import annotations

import numpy as np
import pytest

from sbplan.detection.bands import RowBands
from sbplan.detection.calibration import calibrate
from sbplan.detection import Detector
from sbplan.errors import InputError
from sbplan.bench.evaluation import condition_scenes


def test_stack_puts_bands_one_under_the_other_with_an_empty_row_between():
    image = np.arange(20 * 3).reshape(20, 3)
    bands = RowBands([(2, 5), (10, 12)], image.shape)
    out = bands.stack(image, fill=-1)
    assert bands.stacked_shape == (3 + 1 + 2 + 1, 3) == out.shape
    assert np.array_equal(out[0:3], image[2:5]) and np.array_equal(out[4:6], image[10:12])
    assert (out[3] == -1).all() and (out[6] == -1).all()
    assert bands.fraction == pytest.approx(7 / 20)


def test_to_full_maps_stacked_rows_back():
    bands = RowBands([(2, 5), (10, 12)], (20, 3))
    xy = np.array([[1.0, 0.0], [2.5, 2.2], [0.0, 4.0], [1.0, 5.4]])
    assert np.allclose(bands.to_full(xy), [[1.0, 2.0], [2.5, 4.2], [0.0, 10.0], [1.0, 11.4]])
    assert bands.to_full(np.zeros((0, 2))).shape == (0, 2)


def test_around_merges_close_bands_and_aligns_them_to_even_rows():
    square = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    polygons = [square + [0, 11], square + [10, 12], square + [0, 19], square + [0, 40]]
    bands = RowBands.around(polygons, (60, 30), margin=2)
    assert bands.starts.tolist() == [8, 38]
    assert bands.stops.tolist() == [26, 48]  # exclusive: row 46 is the last one needed
    assert (bands.starts % 2 == 0).all() and (bands.stops % 2 == 0).all()
    edge = RowBands.around([square + [0, 55]], (59, 30), margin=3)
    assert edge.stops.tolist() == [59]


@pytest.mark.parametrize("ranges", [[], [(5, 3)], [(0, 4), (4, 8)], [(0, 4), (2, 8)], [(0, 70)], [(-1, 4)]])
def test_bad_ranges_are_refused(ranges):
    with pytest.raises(InputError, match="row bands"):
        RowBands(ranges, (60, 30))


def test_stack_refuses_an_image_of_another_size():
    with pytest.raises(InputError, match="row bands"):
        RowBands([(0, 4)], (60, 30)).stack(np.zeros((50, 30)))


@pytest.mark.parametrize("condition", ["clean", "shadows", "tilt", "distortion"])
def test_detection_in_bands_finds_what_whole_frames_find(condition):
    scenes = list(condition_scenes(condition, scenes=3, size=(640, 480), grid=(8, 5), seed=5))
    cal = calibrate(scenes[0][0])
    banded, whole = Detector(cal), Detector(cal, row_bands=False)
    assert banded.bands is not None and whole.bands is None
    assert banded.bands.fraction < 0.8
    for _, image, truth in scenes:
        a, b = banded.find_cells(image), whole.find_cells(image)
        assert np.array_equal(a.occupied, b.occupied)
        assert np.allclose(a.matched_centres_px, b.matched_centres_px)
        assert a.occupied.any() and not a.occupied.all()


def test_dense_rows_fall_back_to_whole_frames():
    # 8 rows of symbols on 320 rows: the bands would cover nearly every row and save nothing
    scenes = list(condition_scenes("clean", scenes=1, size=(320, 320), grid=(6, 8), seed=2))
    det = Detector(calibrate(scenes[0][0]))
    assert det.bands is None
    assert RowBands.around(det.calibration.symbol_polygons, (320, 320), margin=6).fraction > 0.8


def test_to_stacked_inverts_to_full_inside_the_bands():
    bands = RowBands([(2, 5), (10, 12)], (20, 3))
    full = np.array([[1.0, 2.0], [2.5, 4.2], [0.0, 10.0], [1.0, 11.4]])
    assert np.allclose(bands.to_stacked(full), [[1.0, 0.0], [2.5, 2.2], [0.0, 4.0], [1.0, 5.4]])
    assert np.allclose(bands.to_full(bands.to_stacked(full)), full)
    # between bands: the separator row after the band above
    assert np.allclose(bands.to_stacked([[0.0, 7.0]]), [[0.0, 3.0]])


def test_outlines_map_to_and_from_the_stacked_image_as_their_points_do():
    # outlines inside one band, across two, between bands, above the first and below the last
    bands = RowBands([[10, 60], [100, 160], [200, 260]], (300, 400))
    rng = np.random.default_rng(0)
    for _ in range(500):
        k, n = int(rng.integers(1, 6)), int(rng.integers(1, 10))
        spread = rng.choice([2.0, 30.0, 100.0]) * rng.uniform(0, 1, (k, 1, 1))
        outlines = rng.uniform(-20, 320, (k, 1, 2)) + rng.uniform(-1, 1, (k, n, 2)) * spread
        want = bands.to_stacked(outlines.reshape(-1, 2)).reshape(outlines.shape)
        np.testing.assert_array_equal(bands.to_stacked_outlines(outlines), want)
        stacked = outlines * [1.0, 0.6]  # (the stacked image is 183 rows high)
        want = bands.to_full(stacked.reshape(-1, 2)).reshape(stacked.shape)
        np.testing.assert_array_equal(bands.to_full_outlines(stacked), want)
    # an outline with a point that is not finite, and points that are not (K, N, 2)
    odd = np.array([[[5.0, 20.0], [np.nan, 70.0], [6.0, 120.0]], [[1.0, 30.0], [2.0, 31.0], [3.0, 32.0]]])
    np.testing.assert_array_equal(bands.to_full_outlines(odd), bands.to_full(odd.reshape(-1, 2)).reshape(odd.shape))
    np.testing.assert_array_equal(bands.to_stacked_outlines(odd), bands.to_stacked(odd.reshape(-1, 2)).reshape(odd.shape))
    flat = odd[1]
    np.testing.assert_array_equal(bands.to_full_outlines(flat), bands.to_full(flat))
