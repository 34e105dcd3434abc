"""The built-in binarizers' fast paths give exactly what their plain forms give."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import sbplan.registry as plugins
from sbplan.detection.bands import RowBands
from sbplan_binarizers.background import _max_filter


@pytest.mark.parametrize("size", [1, 2, 3, 5, 8, 17, 34, 35, 64])
@pytest.mark.parametrize("shape", [(48, 64), (7, 5), (1, 90), (90, 1)])
def test_max_filter_is_opencvs_dilation(size, shape):
    image = np.random.default_rng(size * 31 + shape[0]).integers(0, 256, shape, dtype=np.uint8)
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (size, size))
    assert np.array_equal(_max_filter(image, size), cv2.dilate(image, kernel, borderType=cv2.BORDER_REPLICATE))


@pytest.mark.parametrize("name", ["background", "local-mean"])
def test_level_of_some_rows_is_the_whole_levels_rows(name):
    binarizer = plugins.binarizer(name, window=30)
    small = np.random.default_rng(3).integers(0, 256, (120, 90), dtype=np.uint8)
    rows = [(0, 7), (20, 41), (60, 61), (100, 120)]
    whole = binarizer.local_level(small, 15)
    for (a, b), part in zip(rows, binarizer.local_level_rows(small, 15, rows)):
        assert np.array_equal(part, whole[a:b])


@pytest.mark.parametrize("name", ["background", "local-mean", "otsu"])
def test_bands_are_the_whole_mask_away_from_band_edges(name):
    from sbplan.testing import make_tiny_floor

    gray = np.array(make_tiny_floor(condition="shadows").scene)
    binarizer = plugins.binarizer(name).with_symbol_size(24) if name != "otsu" else plugins.binarizer(name)
    bands = RowBands([(10, 70), (100, 164), (200, 238)], gray.shape)
    stacked = binarizer.binarize_bands(gray, bands)
    whole = bands.stack(binarizer.binarize(gray), fill=False)
    for a, b, o in zip(bands.starts.tolist(), bands.stops.tolist(), bands.offsets.tolist()):
        inner = slice(o + 4, o + b - a - 4)
        assert np.array_equal(stacked[inner], whole[inner])


@pytest.mark.parametrize("name", ["background", "local-mean"])
def test_a_crop_is_the_whole_mask_beyond_the_reach_it_promises(name):
    from sbplan.testing import make_tiny_floor
    from sbplan.testing.checks import check_binarizer_locality

    binarizer = plugins.binarizer(name).with_symbol_size(24)
    reach, step = binarizer.locality()
    assert (reach, step) == {"background": (24, 2), "local-mean": (34, 4)}[name]  # the crops' inner parts are checked
    check_binarizer_locality(binarizer)
    # the promise is not idle: nearer a crop's edge the mask differs (the level sees less floor)
    gray = np.array(make_tiny_floor(condition="shadows").scene)
    whole = binarizer.binarize(gray)
    crops = [(x, y, x + 80, y + 60) for x in range(0, 200, 24) for y in range(0, 150, 24)]
    assert any(not np.array_equal(binarizer.binarize(gray[y0:y1, x0:x1]), whole[y0:y1, x0:x1])
               for x0, y0, x1, y1 in crops)


def test_a_global_threshold_promises_no_locality():
    assert plugins.binarizer("otsu").locality() is None
