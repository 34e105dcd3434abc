"""The per-frame path's small-array helpers give numpy's and OpenCV's own answers."""

import cv2
import numpy as np
import pytest

from sbplan.detection._small import components, median, percentile


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint8])
def test_percentile_and_median_are_numpys_bit_for_bit(dtype):
    rng = np.random.default_rng(0)
    for trial in range(600):
        n = int(rng.integers(1, 120))
        values = rng.integers(0, 256, n).astype(dtype) if dtype is np.uint8 else (rng.random(n) * 255).astype(dtype)
        if trial % 4 == 0:
            values = values.reshape(1, -1)  # any shape: the values are taken flat
        for q in (0, 25, 40, 50, 90, 95, 100):
            assert percentile(values, q) == float(np.percentile(values, q)), (n, q)
        # (median averages the middle two in float64; numpy averages float32 in float32)
        assert median(values) == pytest.approx(float(np.median(values)), rel=1e-6)
        if dtype is not np.float32:
            assert median(values) == float(np.median(values))


def test_percentile_of_nothing_is_nan():
    assert np.isnan(percentile(np.zeros(0, np.float32), 50))


def test_components_are_opencvs_default_labelling():
    rng = np.random.default_rng(1)
    for trial in range(300):
        h, w = (int(v) for v in rng.integers(3, 150, 2))
        mask = (rng.random((h, w)) > rng.random()).astype(np.uint8)
        if trial % 3 == 0:
            mask = cv2.dilate(mask, np.ones((3, 3), np.uint8))  # larger pieces
        n, labels, stats, centroids = components(mask)
        n0, labels0, stats0, centroids0 = cv2.connectedComponentsWithStats(mask, connectivity=8)
        assert n == n0
        assert np.array_equal(labels, labels0) and np.array_equal(stats, stats0)
        assert np.array_equal(centroids, centroids0, equal_nan=True)
