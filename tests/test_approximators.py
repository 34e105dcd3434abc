"""Approximators kka and douglas-peucker on contours of images rendered here with OpenCV."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import sbplan.registry as plugins
from sbplan.contours import FREEMAN_STEPS, Contour
from sbplan.errors import ContourError, InputError
from sbplan_approximators._common import contour_chain, polygon_deviation
from sbplan_approximators.kka import KKA, is_digital_straight, straight_pieces

NAMES = ["kka", "douglas-peucker"]


def contours_of(mask):
    """Contours of a binary image via cv2.findContours (CHAIN_APPROX_NONE), as sbplan Contours."""
    found, hier = cv2.findContours(mask.astype(np.uint8), cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    out = []
    for c, h in zip(found, hier[0]):
        p = c[:, 0].astype(np.int64)
        hole = bool(h[3] >= 0)
        chain = contour_chain(None, p.astype(float)).astype(np.uint8)
        assert np.array_equal(np.roll(p, -1, axis=0) - p, FREEMAN_STEPS[chain])
        out.append(Contour(points=p, is_hole=hole, orientation=-1 if hole else 1, chain=chain))
    return out


def blank(size=140):
    return np.zeros((size, size), np.uint8)


def assert_near(vertices, expected, tol):
    """Every expected corner has a vertex within tol, and there are as many vertices as corners."""
    assert len(vertices) == len(expected)
    d = np.hypot(*(vertices[:, None, :] - np.asarray(expected, float)[None, :, :]).transpose(2, 0, 1))
    assert d.min(axis=0).max() <= tol


@pytest.mark.parametrize("name", NAMES)
def test_axis_rectangle_gives_its_four_corners(name):
    img = blank()
    cv2.rectangle(img, (10, 20), (60, 70), 255, -1)
    outer = contours_of(img)[0]
    v = plugins.approximator(name).approximate(outer)
    assert v.dtype == np.float64 and v.shape == (4, 2)
    assert_near(v, [(10, 20), (10, 70), (60, 70), (60, 20)], 0.0)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("angle", [7.0, 20.0, 33.0, 45.0, 71.0])
def test_rotated_rectangle_gives_four_corners_near_the_true_ones(name, angle):
    img = blank()
    box = cv2.boxPoints(((70, 70), (80, 44), angle))
    cv2.fillPoly(img, [np.round(box).astype(np.int32)], 255)
    outer = contours_of(img)[0]
    v = plugins.approximator(name).approximate(outer)
    # corners of the rasterized box lie within ~1.5 px of the rounded box corners
    assert_near(v, np.round(box), 2.0)


@pytest.mark.parametrize("name", NAMES)
def test_vertices_lie_on_the_contour_and_deviation_is_bounded(name):
    img = blank(160)
    pts = np.array([[20, 30], [90, 12], [140, 60], [100, 80], [120, 140], [40, 120], [60, 70]], np.int32)
    cv2.fillPoly(img, [pts], 255)
    cv2.circle(img, (70, 95), 12, 0, -1)  # a hole
    for c in contours_of(img):
        v = plugins.approximator(name).approximate(c)
        assert len(v) >= 3
        # vertices are contour pixels
        assert {tuple(p) for p in v.astype(int)} <= {tuple(p) for p in c.points}
        # the traversal sense is kept
        area = -0.5 * np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])
        assert np.sign(area) == c.orientation
        # every contour pixel is close to the polygon (1.5 px DP tolerance; KKA 1 px + noise merge)
        assert polygon_deviation(c.points.astype(float), v) <= 2.0


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("radius", [25, 50])
def test_circle_area_within_a_few_percent(name, radius):
    img = blank(2 * radius + 20)
    cv2.circle(img, (radius + 10, radius + 10), radius, 255, -1)
    v = plugins.approximator(name).approximate(contours_of(img)[0])
    area = 0.5 * abs(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]))
    # the polygon runs through boundary pixel centres, about half a pixel inside the disk's edge,
    # so compare with the disk of radius r - 0.5: within 4 % (chords cut the arcs a little more)
    disk = np.pi * (radius - 0.5) ** 2
    assert abs(area - disk) <= 0.04 * disk
    assert len(v) >= 8


def bresenham_chain(dx, dy, steps):
    """Freeman codes of the 8-connected digital straight line of slope dy/dx (0 <= dy <= dx)."""
    x = np.arange(steps + 1)
    y = np.floor(x * dy / dx + 0.5).astype(int)
    rise = np.diff(y)
    return np.where(rise == 0, 0, 1)


@pytest.mark.parametrize("dx,dy", [(5, 2), (7, 3), (1, 0), (1, 1), (13, 4), (3, 1)])
def test_digital_straight_line_is_one_piece(dx, dy):
    chain = bresenham_chain(dx, dy, 60)
    assert is_digital_straight(chain)
    # any rotation by multiples of 45 degrees stays straight
    assert is_digital_straight((chain + 3) % 8)


def test_non_straight_chains_are_rejected_and_split():
    assert not is_digital_straight([0, 0, 2, 2])        # codes not adjacent
    assert not is_digital_straight([0, 1, 1, 0, 0])     # both codes in runs longer than 1
    assert not is_digital_straight([0, 1, 0, 1, 0, 0, 0, 0, 1, 0])  # interior runs 1 and 4
    # a closed square 10x10: four straight pieces starting at its corners
    chain = np.repeat([6, 0, 2, 4], 10)
    assert straight_pieces(chain).tolist() == [0, 10, 20, 30]


def test_kka_staircase_triangle_keeps_one_segment_per_side():
    img = blank()
    # the long side has slope 2/5: a digital straight line (staircase), 100 px long
    cv2.fillPoly(img, [np.array([[5, 5], [105, 45], [5, 45]], np.int32)], 255)
    v = KKA().approximate(contours_of(img)[0])
    assert_near(v, [(5, 5), (5, 45), (105, 45)], 0.0)


def test_kka_merges_noise_chains():
    img = blank()
    cv2.rectangle(img, (20, 20), (100, 80), 255, -1)
    img[19, 60] = 255  # a one-pixel bump on the top edge
    img[50, 101] = 255  # and on the right edge
    v = KKA().approximate(contours_of(img)[0])
    assert_near(v, [(20, 20), (20, 80), (100, 80), (100, 20)], 0.0)
    # without noise merging and with no chord merging, the bumps stay
    raw = KKA(noise_length=0, max_deviation=0.0).approximate(contours_of(img)[0])
    assert len(raw) > 4


@pytest.mark.parametrize("name", NAMES)
def test_short_contours_raise_contour_error(name):
    a = plugins.approximator(name)
    with pytest.raises(ContourError):
        a.approximate(Contour(points=np.array([[0, 0], [1, 0]]), chain=np.array([0, 4], np.uint8)))
    with pytest.raises(ContourError):
        a.approximate(np.array([[0, 0], [1, np.nan], [1, 1]]))


def test_kka_needs_an_8_connected_path_without_a_chain():
    with pytest.raises(ContourError, match="8-connected"):
        KKA().approximate(np.array([[0, 0], [5, 0], [5, 5]], float))


def test_options_are_validated():
    with pytest.raises(InputError, match="epsilon"):
        plugins.approximator("douglas-peucker", epsilon=-1)
    with pytest.raises(InputError, match="relative"):
        plugins.approximator("douglas-peucker", relative=0.7)
    with pytest.raises(InputError, match="noise_length"):
        KKA(noise_length=-2)
    with pytest.raises(InputError, match="max_deviation"):
        KKA(max_deviation=float("nan"))


def test_douglas_peucker_relative_epsilon_simplifies_more():
    img = blank()
    cv2.circle(img, (70, 70), 50, 255, -1)
    c = contours_of(img)[0]
    fine = plugins.approximator("douglas-peucker").approximate(c)
    coarse = plugins.approximator("douglas-peucker", relative=0.02).approximate(c)
    assert 3 <= len(coarse) < len(fine)


# -- douglas-peucker's compiled loop gives OpenCV's vertices ------------------------------------------
#
# approximate_many runs its own loop over all contours (sbplan_approximators._kernels) instead of
# one cv2.approxPolyDP call per contour: the same steps, so the same vertices, on real contours and
# on arbitrary closed point lists (repeated points, reversals, collinear runs).


def _dp_batch(point_lists, eps):
    from sbplan_approximators._kernels import douglas_peucker
    starts = np.zeros(len(point_lists) + 1, np.int64)
    starts[1:] = np.cumsum([len(p) for p in point_lists])
    vertices, counts = douglas_peucker(np.concatenate(point_lists).astype(np.int32), starts, eps * eps)
    return np.split(vertices, np.cumsum(counts)[:-1])


@pytest.mark.parametrize("condition", ["clean", "noise", "worn", "rotation"])
def test_compiled_douglas_peucker_equals_opencv_on_a_rendered_floor(condition):
    from sbplan.synth import FloorSpec, SceneSpec, render_scene
    image, _ = render_scene(FloorSpec(width=640, height=480, cols=6, rows=4), SceneSpec(condition=condition), seed=3)
    mask = cv2.adaptiveThreshold(image, 1, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, 31, 10)
    found, _ = cv2.findContours(mask, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    found = [c.reshape(-1, 2) for c in found]
    assert len(found) > 20
    for eps in (0.5, 1.5, 3.0):
        ours = _dp_batch(found, eps)
        for c, got in zip(found, ours):
            assert np.array_equal(got, cv2.approxPolyDP(c, eps, True).reshape(-1, 2))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.integers(-40, 40), st.integers(-40, 40)), min_size=1, max_size=60),
       st.sampled_from([0.0, 0.5, 1.0, 1.5, 2.0, 7.5]))
def test_compiled_douglas_peucker_equals_opencv_on_any_closed_points(points, eps):
    pts = np.array(points, np.int32)
    try:
        expected = cv2.approxPolyDP(pts, eps, True).reshape(-1, 2)
    except cv2.error:  # (OpenCV refuses some degenerate lists: nothing to compare with)
        return
    assert np.array_equal(_dp_batch([pts], eps)[0], expected)


def test_douglas_peucker_many_equals_one_by_one_on_extracted_contours():
    img = blank(200)
    cv2.circle(img, (60, 60), 35, 1, -1)
    cv2.fillPoly(img, [np.array([[120, 20], [190, 40], [150, 120]], np.int32)], 1)
    cv2.rectangle(img, (20, 130), (90, 180), 1, -1)
    found, _ = cv2.findContours(img, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contours = Contour.outers_unchecked([c.reshape(-1, 2) for c in found], np.zeros(0, np.uint8))
    stage = plugins.registry().create("approximator", "douglas-peucker")
    batch = stage.approximate_many(contours)
    assert len(batch) == len(contours)
    for k, c in enumerate(contours):
        assert np.array_equal(batch[k], cv2.approxPolyDP(c.points, 1.5, True).reshape(-1, 2).astype(float))


def test_douglas_peucker_many_takes_opencv_beyond_the_exact_span():
    # coordinates so far apart that the compiled loop's whole numbers would overflow: OpenCV's call
    rng = np.random.default_rng(5)
    points = (rng.integers(0, 60_000, (7, 2))).astype(np.int32)
    square = np.array([[x, 0] for x in range(10)] + [[9, y] for y in range(1, 10)] + [[x, 9] for x in range(8, -1, -1)]
                      + [[0, y] for y in range(8, 0, -1)], np.int32)
    contours = Contour.outers_unchecked([points, square], np.zeros(0, np.uint8))
    batch = plugins.registry().create("approximator", "douglas-peucker").approximate_many(contours)
    for k, c in enumerate(contours):
        want = cv2.approxPolyDP(c.points, 1.5, True).reshape(-1, 2).astype(float)
        assert len(want) >= 3 and np.array_equal(batch[k], want)
