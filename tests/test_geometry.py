"""sbplan.polygons: equation (1), areas, perimeters, resampling and the length filter."""

import numpy as np
import pytest
import shapely
from hypothesis import given, settings, strategies as st

from sbplan import polygons as g
from sbplan.contours import Contour
from sbplan.errors import ContourError, InputError


def star_polygon(seed, n=None, *, center=(0.0, 0.0), scale=1.0):
    """A random star-shaped simple polygon (vertices sorted by angle around its centre)."""
    rng = np.random.default_rng(seed)
    n = n or int(rng.integers(3, 40))
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    t += np.linspace(0, 1e-3, n)  # strictly increasing angles
    r = rng.uniform(0.3, 1.0, n) * scale
    return np.c_[center[0] + r * np.cos(t), center[1] + r * np.sin(t)]


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), cx=st.floats(-1e4, 1e4), cy=st.floats(-1e4, 1e4),
       scale=st.floats(0.5, 500))
def test_centroid_equation_1_equals_shapely(seed, cx, cy, scale):
    p = star_polygon(seed, center=(cx, cy), scale=scale)
    expect = shapely.Polygon(p).centroid
    got = g.centroid(p)
    # 1e-9 relative to the polygon's extent and position
    tol = 1e-9 * max(scale, abs(cx), abs(cy), 1.0)
    assert abs(got[0] - expect.x) <= tol and abs(got[1] - expect.y) <= tol
    # traversal direction does not matter; the batched version agrees
    back = g.centroid(p[::-1])
    assert np.allclose(back, got, rtol=0, atol=tol)
    many = g.centroids([p, p[::-1], p + 1.0])
    assert np.allclose(many[:2], got, rtol=0, atol=tol)
    assert np.allclose(many[2], np.add(got, 1.0), rtol=0, atol=tol)


def test_signed_area_orientation_follows_display():
    # (0,0) -> (0,1) -> (1,1) -> (1,0) goes down, right, up: counter-clockwise as displayed (y down)
    ccw = np.array([[0, 0], [0, 1], [1, 1], [1, 0]], float)
    assert g.signed_area(ccw) == pytest.approx(1.0)
    assert g.signed_area(ccw[::-1]) == pytest.approx(-1.0)
    assert np.allclose(g.signed_areas([ccw, ccw[::-1] * 2]), [1.0, -4.0])


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_area_and_perimeter_match_shapely(seed):
    p = star_polygon(seed, scale=50.0)
    poly = shapely.Polygon(p)
    assert abs(g.signed_area(p)) == pytest.approx(poly.area, rel=1e-9)
    assert g.perimeter(p) == pytest.approx(poly.length, rel=1e-12)
    assert g.perimeters([p, p * 2])[1] == pytest.approx(2 * poly.length, rel=1e-12)


def test_centroid_zero_area_raises():
    with pytest.raises(ContourError, match="no area"):
        g.centroid([[0, 0], [1, 1], [2, 2]])
    with pytest.raises(ContourError, match=r"polygons\[1\]"):
        g.centroids([star_polygon(1), np.array([[0, 0], [1, 0], [2, 0.0]])])
    out = g.centroids([star_polygon(1), np.array([[0, 0], [1, 0], [2, 0.0]])], on_zero_area="nan")
    assert np.isfinite(out[0]).all() and np.isnan(out[1]).all()


@pytest.mark.parametrize("bad", [[[0, 0], [1, 1]], [[0, 0], [1, np.nan], [2, 3]], [[0, 0, 0]] * 3, "abc"])
def test_bad_points_raise_contour_error(bad):
    for fn in (g.centroid, g.signed_area, g.perimeter, lambda p: g.resample_closed(p, 16)):
        with pytest.raises(ContourError):
            fn(bad)


def test_bad_polygon_in_batch_is_named():
    with pytest.raises(ContourError, match=r"polygons\[2\]"):
        g.resample_many([star_polygon(1), star_polygon(2), [[0, 0], [1, 1]]], 16)


def test_resample_equal_arc_length_steps():
    square = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float)
    r = g.resample_closed(square, 8)
    assert np.allclose(r, [[0, 0], [2, 0], [4, 0], [4, 2], [4, 4], [2, 4], [0, 4], [0, 2]])
    # duplicate points (zero-length edges) are harmless
    dup = np.array([[0, 0], [0, 0], [4, 0], [4, 4], [4, 4], [0, 4]], float)
    assert np.allclose(g.resample_closed(dup, 8), r)
    many = g.resample_many([square, square[::-1] + 10], 8)
    assert many.shape == (2, 8, 2)
    assert np.allclose(many[0], r)
    with pytest.raises(InputError, match="samples"):
        g.resample_closed(square, 2)
    with pytest.raises(ContourError, match="zero perimeter"):
        g.resample_closed([[1, 1]] * 4, 8)


def test_length_filter_on_lengths_and_contours():
    assert g.length_filter([3.0, 5.0, 10.0], min_length=4, max_length=9).tolist() == [False, True, False]
    # a 2x2 pixel square: 4 axis steps; a diagonal diamond: 4 diagonal steps
    sq = Contour(points=np.array([[0, 0], [0, 1], [1, 1], [1, 0]]), chain=np.array([6, 0, 2, 4], np.uint8))
    dia = Contour(points=np.array([[1, 0], [0, 1], [1, 2], [2, 1]]), chain=np.array([5, 7, 1, 3], np.uint8))
    assert g.contour_length(sq) == 4.0
    assert g.contour_length(dia) == pytest.approx(4 * np.sqrt(2))
    assert g.length_filter([sq, dia], min_length=4.5).tolist() == [False, True]
    with pytest.raises(InputError, match="max_length"):
        g.length_filter([1.0], min_length=5, max_length=2)
    with pytest.raises(InputError, match="min_length"):
        g.length_filter([1.0], min_length=-1)


def test_polygon_batch_is_a_sequence_that_pack_takes_as_is():
    from sbplan.polygons import PolygonBatch, centroids, pack, resample_xy

    rng = np.random.default_rng(4)
    polys = [rng.random((n, 2)) * 50 for n in (3, 7, 4)]
    batch = PolygonBatch.from_list(polys)
    assert len(batch) == 3 and all(np.array_equal(a, b) for a, b in zip(batch, polys))
    points, starts, counts = pack(batch)
    assert points is batch.points and starts.tolist() == [0, 3, 10] and counts.tolist() == [3, 7, 4]
    assert np.array_equal(g.signed_areas(batch), g.signed_areas(polys))
    assert np.allclose(centroids(batch), centroids(polys))
    assert all(np.array_equal(a, b) for a, b in zip(resample_xy(batch, 16), resample_xy(polys, 16)))
    picked = batch.take([2, 0])
    assert [len(p) for p in picked] == [4, 3] and np.array_equal(picked[0], polys[2])
    assert len(batch.take(np.array([False, True, False]))) == 1 and len(batch.take([])) == 0
    assert np.array_equal(batch[1:][0], polys[1])
    boxes = np.array([[*p.min(axis=0), *p.max(axis=0)] for p in polys])
    assert np.array_equal(batch.boxes(), boxes) and np.array_equal(batch.boxes(np.array([2, 0])), boxes[[2, 0]])
    assert batch.boxes(np.zeros(0, np.int64)).shape == (0, 4)


@pytest.mark.parametrize("points, counts", [(np.zeros((5, 2)), [2, 3]), (np.zeros((5, 2)), [3, 3]),
                                            (np.full((3, 2), np.nan), [3])])
def test_polygon_batch_refuses_bad_outlines(points, counts):
    from sbplan.polygons import PolygonBatch

    with pytest.raises(ContourError, match="PolygonBatch"):
        PolygonBatch(points, counts)


def test_resample_complex_and_xy_agree_for_lists_and_batches():
    from sbplan.polygons import PolygonBatch, resample_complex, resample_xy

    polys = [star_polygon(s, center=(40.0 * s, 7.0), scale=20.0) for s in range(6)]
    z = resample_complex(polys, 32)
    x, y = resample_xy(polys, 32)
    assert z.shape == (6, 32) and np.allclose(z.real, x, atol=1e-9) and np.allclose(z.imag, y, atol=1e-9)
    batch = PolygonBatch.from_list(polys)
    zb = resample_complex(batch, 32)
    assert np.allclose(zb, z, atol=1e-9)
    # a later call for a divisor of n reads every other sample of the remembered one
    x16, _ = resample_xy(batch, 16)
    assert np.array_equal(x16, zb.real[:, ::2])


def _resample_interp(points, n):
    """One closed outline sampled at j/n of its perimeter by np.interp over its cumulative arc
    length: the numpy expression the compiled loop replaced."""
    closed = np.vstack([points, points[:1]])
    cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))])
    t = cum[-1] * np.arange(n) / n
    return np.stack([np.interp(t, cum, closed[:, 0]), np.interp(t, cum, closed[:, 1])], axis=1)


@settings(max_examples=60, deadline=None)
@given(seeds=st.lists(st.integers(0, 2**32 - 1), min_size=1, max_size=8), n=st.integers(3, 300),
       cx=st.floats(-1e4, 1e4), scale=st.floats(0.01, 500), repeat=st.integers(0, 3))
def test_compiled_centres_and_samples_agree_with_numpy(seeds, n, cx, scale, repeat):
    # The compiled loops of a whole batch against the plain per-outline numpy (shapely's centre,
    # np.interp's samples), with repeated vertices (zero-length edges) in some outlines.
    from sbplan.polygons import PolygonBatch, centroids, resample_complex

    polys = []
    for s in seeds:
        p = star_polygon(s, center=(cx, -cx / 3), scale=scale)
        polys.append(np.repeat(p, [1 + repeat * (i % 2) for i in range(len(p))], axis=0))
    batch = PolygonBatch.from_list(polys)
    centres, areas = centroids(batch, return_areas=True)
    extent = scale + abs(cx)
    for p, c, a in zip(polys, centres, areas):
        poly = shapely.Polygon(p)
        assert np.allclose(c, [poly.centroid.x, poly.centroid.y], rtol=0, atol=1e-9 * extent)
        assert a == pytest.approx(poly.area, rel=1e-9, abs=1e-9 * extent ** 2)
    z = resample_complex(batch, n)
    for p, row in zip(polys, z):
        assert np.allclose(np.stack([row.real, row.imag], axis=1), _resample_interp(p, n), rtol=0,
                           atol=1e-9 * extent)


@pytest.mark.parametrize("matrix", [
    [[1.002, -0.01, 3.5], [0.01, 1.002, -2.0], [0.0, 0.0, 1.0]],  # a camera's similarity
    [[0.98, 0.03, 12.0], [-0.02, 1.01, 4.0], [2e-5, -1e-5, 1.0]],  # a tilted camera's homography
])
def test_apply_homography_maps_points_of_any_shape(matrix):
    m = np.asarray(matrix)
    rng = np.random.default_rng(1)
    xy = rng.uniform(-50, 1300, (4, 7, 2))
    w = xy[..., 0] * m[2, 0] + xy[..., 1] * m[2, 1] + m[2, 2]
    want = np.stack([(xy[..., 0] * m[0, 0] + xy[..., 1] * m[0, 1] + m[0, 2]) / w,
                     (xy[..., 0] * m[1, 0] + xy[..., 1] * m[1, 1] + m[1, 2]) / w], axis=-1)
    got = g.apply_homography(m, xy)
    assert got.shape == xy.shape
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    np.testing.assert_allclose(g.apply_homography(m, xy[0, 0]), want[0, 0], rtol=0, atol=1e-9)
    assert g.apply_homography(m, np.zeros((0, 2))).shape == (0, 2)
    np.testing.assert_allclose(g.apply_homography(m, xy[:, ::2]), want[:, ::2], rtol=0, atol=1e-9)  # a strided view


def test_apply_homography_keeps_the_arithmetics_inf_and_nan():
    # a point on the horizon line of a projective map goes to infinity, a NaN point stays NaN
    # (OpenCV's perspectiveTransform would give (0, 0) for both)
    m = np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 0, 0]])
    with np.errstate(divide="ignore", invalid="ignore"):
        out = g.apply_homography(m, np.array([[0.0, 1.0], [np.nan, 1.0], [2.0, 3.0]]))
    assert np.isinf(out[0, 1]) and np.isnan(out[1]).all()
    np.testing.assert_allclose(out[2], [1.0, 1.5])
