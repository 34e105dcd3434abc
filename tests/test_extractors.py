"""Contour extractors ``oke`` (the paper's 2x2-window method) and ``opencv`` (border following).

Everything runs the real extractors through the plugin registry; images are drawn here.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

import sbplan.registry as plugins
from sbplan.contours import FREEMAN_STEPS
from sbplan.errors import ImageError, InputError

NAMES = ("oke", "opencv")


@pytest.fixture(scope="module")
def extractors():
    return {name: plugins.extractor(name) for name in NAMES}


@st.composite
def masks(draw):
    """Small random binary images of random density, sometimes upscaled so that regions are
    thicker than one pixel and holes appear."""
    h = draw(st.integers(1, 24))
    w = draw(st.integers(1, 24))
    density = draw(st.floats(0.05, 0.95))
    seed = draw(st.integers(0, 2**32 - 1))
    mask = np.random.default_rng(seed).random((h, w)) < density
    if draw(st.booleans()):
        mask = np.kron(mask, np.ones((2, 2), bool))[: max(h, 4), : max(w, 4)]
    return mask


def signature(contours):
    """Multiset of (is_hole, frozenset of boundary pixels), as a sorted list."""
    return sorted(((c.is_hole, frozenset(map(tuple, c.points.tolist()))) for c in contours), key=repr)


def shoelace(points: np.ndarray) -> float:
    """Signed area in image coordinates (y down): negative for counter-clockwise as displayed."""
    x, y = points[:, 0].astype(float), points[:, 1].astype(float)
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def check_contour_model(contours, mask):
    """Invariants every extractor's output must satisfy."""
    h, w = mask.shape
    for c in contours:
        pts = c.points
        assert pts.dtype == np.int64 and pts.ndim == 2 and pts.shape[1] == 2 and len(pts) >= 1
        assert (pts[:, 0] >= 0).all() and (pts[:, 0] < w).all() and (pts[:, 1] >= 0).all() and (pts[:, 1] < h).all()
        assert mask[pts[:, 1], pts[:, 0]].all(), "boundary pixels are foreground"
        assert c.orientation == (-1 if c.is_hole else 1)
        if len(pts) == 1:
            assert len(c.chain) == 0
            continue
        assert len(c.chain) == len(pts)
        # Walking the chain from the start point reproduces the points and closes on itself.
        walk = np.asarray(c.start) + np.cumsum(FREEMAN_STEPS[c.chain], axis=0)
        np.testing.assert_array_equal(walk[:-1], pts[1:])
        np.testing.assert_array_equal(walk[-1], pts[0])
        area = shoelace(pts)
        if area != 0:
            assert np.sign(-area) == c.orientation


def check_parents(contours, mask):
    """Parents, checked against connected-component labels computed by OpenCV independently:
    a hole's parent is the outer contour of the same 8-connected region (the one enclosing it);
    an outer contour's parent is -1 when the background to its left reaches the image border,
    otherwise the hole whose background component it sits in."""
    _, fg = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    _, bg = cv2.connectedComponents((~mask).astype(np.uint8), connectivity=4)
    h, w = mask.shape
    border_bg = set(np.unique(np.concatenate([bg[0], bg[-1], bg[:, 0], bg[:, -1]]))) - {0}
    for c in contours:
        x, y = c.start
        if c.is_hole:
            assert 0 <= c.parent < len(contours)
            parent = contours[c.parent]
            assert not parent.is_hole
            assert set(fg[c.points[:, 1], c.points[:, 0]]) == {fg[y, x]} == set(
                fg[parent.points[:, 1], parent.points[:, 0]])
            assert x + 1 < w and not mask[y, x + 1] and bg[y, x + 1] not in border_bg
        else:
            outside = bg[y, x - 1] if x > 0 else None
            if outside is None or outside in border_bg:
                assert c.parent == -1
            else:
                hole = contours[c.parent]
                assert hole.is_hole and bg[hole.start[1], hole.start[0] + 1] == outside


@settings(max_examples=150, deadline=None)
@given(masks())
def test_oke_and_opencv_give_the_same_boundaries(mask):
    """"Same" means: the multiset of (is_hole, frozenset of boundary pixels) is equal, so the
    boundaries match one to one by pixel set, and the counts of outer boundaries and holes agree.
    (The implementation goes further: equal point sequences, start points and parents; that is
    checked too, as the stronger property the docs promise.)"""
    oke = plugins.extractor("oke").extract(mask)
    ocv = plugins.extractor("opencv").extract(mask)
    assert signature(oke) == signature(ocv)
    assert sum(c.is_hole for c in oke) == sum(c.is_hole for c in ocv)
    assert sum(not c.is_hole for c in oke) == sum(not c.is_hole for c in ocv)

    def exact(cs):
        return sorted((tuple(map(tuple, c.points.tolist())),
                       None if c.parent < 0 else tuple(map(tuple, cs[c.parent].points.tolist())))
                      for c in cs)
    assert exact(oke) == exact(ocv)


@settings(max_examples=120, deadline=None)
@given(masks(), st.sampled_from(NAMES))
def test_chains_orientation_and_parents(mask, name):
    contours = plugins.extractor(name).extract(mask)
    check_contour_model(contours, mask)
    check_parents(contours, mask)
    # Every foreground pixel with a 4-neighbour in the background is on some boundary.
    padded = np.pad(mask, 1)
    inner = padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:]
    border = mask & ~inner
    covered = np.zeros_like(mask)
    for c in contours:
        covered[c.points[:, 1], c.points[:, 0]] = True
    np.testing.assert_array_equal(covered, border)


def square(n=12, lo=3, hi=9):
    m = np.zeros((n, n), bool)
    m[lo:hi, lo:hi] = True
    return m


@pytest.mark.parametrize("name", NAMES)
def test_filled_square(name):
    cs = plugins.extractor(name).extract(square())
    assert len(cs) == 1 and not cs[0].is_hole and cs[0].parent == -1
    assert cs[0].start == (3, 3)
    assert len(cs[0]) == 4 * 5
    # Counter-clockwise as displayed: from the top-left corner it goes down first.
    assert tuple(cs[0].points[1]) == (3, 4) and cs[0].chain[0] == 6


@pytest.mark.parametrize("name", NAMES)
def test_ring_has_one_outer_and_one_hole(name):
    m = square(12, 2, 10)
    m[4:8, 4:8] = False
    cs = plugins.extractor(name).extract(m)
    outer = [c for c in cs if not c.is_hole]
    holes = [c for c in cs if c.is_hole]
    assert len(outer) == 1 and len(holes) == 1
    assert cs[holes[0].parent] is outer[0]
    assert holes[0].start == (3, 4)  # the foreground pixel left of the hole's first pixel
    assert holes[0].orientation == -1 and shoelace(holes[0].points) > 0
    # The hole's boundary is the ring of foreground pixels 4-adjacent to the hole.
    assert set(map(tuple, holes[0].points.tolist())) == (
        {(x, 3) for x in range(4, 8)} | {(x, 8) for x in range(4, 8)}
        | {(3, y) for y in range(4, 8)} | {(8, y) for y in range(4, 8)})


@pytest.mark.parametrize("name", NAMES)
def test_nested_island_in_a_hole(name):
    m = square(16, 1, 15)
    m[3:13, 3:13] = False
    m[6:10, 6:10] = True  # an island in the hole
    m[7:9, 7:9] = False  # with its own hole
    cs = plugins.extractor(name).extract(m)
    assert sorted((c.is_hole, len(c)) for c in cs) == [(False, 12), (False, 52), (True, 8), (True, 40)]
    by_len = {len(c): i for i, c in enumerate(cs)}
    assert cs[by_len[52]].parent == -1
    assert cs[by_len[40]].parent == by_len[52]
    assert cs[by_len[12]].parent == by_len[40]  # the island sits in the big hole
    assert cs[by_len[8]].parent == by_len[12]


@pytest.mark.parametrize("name", NAMES)
def test_one_pixel_wide_line_visits_pixels_twice(name):
    m = np.zeros((5, 8), bool)
    m[2, 1:6] = True
    (c,) = plugins.extractor(name).extract(m)
    assert c.points.tolist() == [[1, 2], [2, 2], [3, 2], [4, 2], [5, 2], [4, 2], [3, 2], [2, 2]]
    assert c.chain.tolist() == [0, 0, 0, 0, 4, 4, 4, 4]


@pytest.mark.parametrize("name", NAMES)
def test_diagonal_connection_is_one_region(name):
    m = np.zeros((6, 6), bool)
    m[1, 1] = m[2, 2] = m[3, 3] = True
    cs = plugins.extractor(name).extract(m)
    assert len(cs) == 1
    assert cs[0].points.tolist() == [[1, 1], [2, 2], [3, 3], [2, 2]]
    assert cs[0].chain.tolist() == [7, 7, 3, 3]


@pytest.mark.parametrize("name", NAMES)
def test_single_pixel(name):
    m = np.zeros((3, 3), bool)
    m[1, 1] = True
    (c,) = plugins.extractor(name).extract(m)
    assert c.points.tolist() == [[1, 1]] and len(c.chain) == 0 and not c.is_hole


@pytest.mark.parametrize("name", NAMES)
def test_region_touching_the_border_and_all_foreground(name):
    m = np.zeros((6, 7), bool)
    m[:3, 4:] = True
    (c,) = plugins.extractor(name).extract(m)
    assert c.start == (4, 0) and set(map(tuple, c.points.tolist())) == {
        (4, 0), (5, 0), (6, 0), (4, 1), (6, 1), (4, 2), (5, 2), (6, 2)}
    (full,) = plugins.extractor(name).extract(np.ones((4, 5), bool))
    assert len(full) == 2 * (4 + 5) - 4 and not full.is_hole


@pytest.mark.parametrize("name", NAMES)
def test_empty_image_and_uint8_input(name):
    ex = plugins.extractor(name)
    assert ex.extract(np.zeros((7, 9), bool)) == []
    m = square()
    as255 = ex.extract(m.astype(np.uint8) * 255)
    as01 = ex.extract(m.astype(np.uint8))
    ref = ex.extract(m)
    assert signature(as255) == signature(as01) == signature(ref)
    # Non-contiguous input is fine too.
    assert signature(ex.extract(np.asfortranarray(m))) == signature(ref)


@pytest.mark.parametrize("name", NAMES)
def test_chains_can_be_skipped(name):
    cls = type(plugins.extractor(name))
    with_chains = cls().extract(square())
    without = cls(chains=False).extract(square())
    assert len(without[0].chain) == 0
    np.testing.assert_array_equal(without[0].points, with_chains[0].points)
    with pytest.raises(InputError, match="chains"):
        cls(chains="yes")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("bad", [
    np.zeros((4, 4, 3), np.uint8),
    np.zeros((0, 5), bool),
    np.full((4, 4), 0.5),
    np.array([[0, 7], [1, 0]], np.uint8),
    np.zeros((4, 4), np.int64),
    [[0, 1], [1, 0]],
    "mask",
    None,
], ids=["3d", "empty", "float", "uint8-7", "int64", "list", "str", "none"])
def test_bad_input_raises_image_error_naming_binary(name, bad):
    with pytest.raises(ImageError, match="binary"):
        plugins.extractor(name).extract(bad)


def test_both_extractors_are_registered():
    names = plugins.extractor_names()
    assert "oke" in names and "opencv" in names


def test_bench_stages_reports_every_registered_stage():
    """The benchmark runs (structure only: no timing is asserted here)."""
    from sbplan.bench import stage_timings as bench

    result = bench.measure(repeat=1)
    names = {(r["stage"], r["name"]) for r in result["rows"]}
    for name in plugins.extractor_names():
        assert ("extractor", name) in names
    for name in plugins.approximator_names():
        assert ("approximator", name) in names
    for name in plugins.matcher_names():
        assert ("matcher", f"{name} describe_many") in names
    assert result["symbol_contours"] == bench.N_SYMBOLS
    assert all(r["median_ms"] >= 0 and r["p90_ms"] >= r["median_ms"] for r in result["rows"])
    assert "oke" in bench.format_table(result)
    with pytest.raises(InputError, match="repeat"):
        bench.measure(repeat=0)
