"""sbplan.morphology: an opening that leaves shapes where they are, and the binarizers that use it."""

import cv2
import numpy as np
import pytest

from sbplan.morphology import open_square
from sbplan_binarizers.background import BackgroundBinarizer


def _square_mask() -> np.ndarray:
    mask = np.zeros((40, 40), np.uint8)
    mask[10:20, 12:24] = 1
    mask[30, 5:35] = 1  # a one-pixel streak: no square of side 2 or more fits in it
    return mask


@pytest.mark.parametrize("side", [2, 3, 4, 5, 6])
def test_an_opening_keeps_what_fits_where_it_was(side):
    opened = open_square(_square_mask(), side)
    ys, xs = np.nonzero(opened)
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (12, 23, 10, 19)
    assert not opened[30].any()


def test_an_odd_side_is_opencvs_own_opening():
    mask = (np.random.default_rng(0).random((60, 80)) > 0.4).astype(np.uint8)
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (5, 5))
    assert np.array_equal(open_square(mask, 5), cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel))


def test_opencvs_even_opening_moves_shapes_which_is_why_this_exists():
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (4, 4))
    ys, xs = np.nonzero(cv2.morphologyEx(_square_mask(), cv2.MORPH_OPEN, kernel))
    assert (xs.min(), ys.min()) == (13, 11)


@pytest.mark.parametrize("opening", [3, 4])
def test_a_binarizers_ink_stays_on_the_symbol_at_an_even_opening(opening):
    image = np.full((240, 320), 200, np.uint8)
    image[100:140, 150:190] = 40
    ys, xs = np.nonzero(BackgroundBinarizer(window=68, opening=opening).binarize(image))
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (150, 189, 100, 139)
