"""Matchers fourier, centroid-distance and hu-moments: invariances, distances, errors."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import sbplan.registry as plugins
from sbplan.contracts import DescriptorMatcher
from sbplan.errors import ContourError, InputError

NAMES = ["fourier", "centroid-distance", "hu-moments"]
#: Largest distance between a polygon and an exactly transformed copy (translation, rotation,
#: scale 0.1-100, start point). Arc-length resampling places the samples differently relative to
#: the corners, which bounds the FD agreement at about 1e-3; Hu moments go through float32.
EXACT_TOL = {"fourier": 5e-3, "centroid-distance": 5e-3, "hu-moments": 2e-3}
#: Largest distance between two rasterizations of one polygon at 40-90 px and any rotation.
# Hu's high-order invariants are small and have a heavy tail under re-rasterization: 1 random star
# in 400 lands above 1.0 (up to 1.7), and a targeted search finds 40 px stars near 2.9. The suite
# is derandomized (conftest.py), so this bound is checked on the same examples every run.
RASTER_TOL = {"fourier": 0.1, "centroid-distance": 0.05, "hu-moments": 1.0}


def star(seed, n=None):
    """A random star-shaped polygon with 5-15 vertices, radius 0.4-1, centred at the origin."""
    rng = np.random.default_rng(seed)
    n = n or int(rng.integers(5, 16))
    t = np.sort(rng.uniform(0, 2 * np.pi, n)) + np.linspace(0, 1e-3, n)
    r = rng.uniform(0.4, 1.0, n)
    return np.c_[r * np.cos(t), r * np.sin(t)]


def transform(p, angle, scale, shift):
    c, s = np.cos(angle), np.sin(angle)
    return p @ np.array([[c, -s], [s, c]]).T * scale + shift


def rasterize(p, size=200):
    """Fill the polygon (sub-pixel vertices) and return its largest outer pixel contour (N, 2)."""
    img = np.zeros((size, size), np.uint8)
    cv2.fillPoly(img, [np.round(p * 16).astype(np.int32)], 255, shift=4)
    found, _ = cv2.findContours(img, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    return max(found, key=cv2.contourArea)[:, 0].astype(np.int64)


@pytest.fixture(params=NAMES)
def matcher(request):
    return plugins.matcher(request.param)


def test_registered_with_docs_and_threshold():
    for name in NAMES:
        m = plugins.matcher(name)
        assert isinstance(m, DescriptorMatcher)
        assert m.default_threshold > 0
        assert "distance" in type(m).__doc__.lower() and "threshold" in type(m).__doc__.lower()


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), angle=st.floats(0, 2 * np.pi), scale=st.floats(0.1, 100),
       dx=st.floats(-1e3, 1e3), dy=st.floats(-1e3, 1e3), roll=st.integers(0, 100), name=st.sampled_from(NAMES))
def test_invariant_to_exact_similarity_transforms_and_start_point(seed, angle, scale, dx, dy, roll, name):
    m = plugins.matcher(name)
    p = star(seed)
    q = np.roll(transform(p, angle, scale, (dx, dy)), roll % len(p), axis=0)
    a, b = m.describe(p), m.describe(q)
    assert a.shape == b.shape and np.isfinite(a).all() and np.isfinite(b).all()
    assert m.distance(a, b) <= EXACT_TOL[name]


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), angle=st.floats(0, 2 * np.pi), scale=st.floats(40, 90),
       name=st.sampled_from(NAMES))
def test_invariant_to_rerasterization(seed, angle, scale, name):
    m = plugins.matcher(name)
    p = star(seed)
    a = m.describe(rasterize(transform(p, 0.0, 60.0, (100, 100))))
    b = m.describe(rasterize(transform(p, angle, scale, (100, 100))))
    assert m.distance(a, b) <= RASTER_TOL[name]


def test_reversed_traversal_and_hole_give_the_same_descriptor(matcher):
    p = star(7) * 50 + 100
    a, b = matcher.describe(p), matcher.describe(p[::-1])
    assert matcher.distance(a, b) <= EXACT_TOL[matcher.name]
    # a hole of the same shape, as OpenCV traces it (clockwise), against the outer boundary
    img = np.full((220, 220), 255, np.uint8)
    cv2.fillPoly(img, [np.round((star(7) * 60 + 110) * 16).astype(np.int32)], 0, shift=4)
    found, hier = cv2.findContours(img, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    hole = next(c[:, 0] for c, h in zip(found, hier[0]) if h[3] >= 0)
    outer = rasterize(star(7) * 60 + 110, 220)
    assert matcher.distance(matcher.describe(hole), matcher.describe(outer)) <= RASTER_TOL[matcher.name]


def test_fourier_tells_mirror_images_apart_and_amplitudes_alone_do_not():
    p = star(3, 9) * 50
    mirrored = p * [-1, 1]
    m = plugins.matcher("fourier")
    # chirality terms flip sign under mirroring; the paper's amplitudes are identical
    assert m.distance(m.describe(p), m.describe(mirrored)) > 0.05
    pure = plugins.matcher("fourier", mirror_terms=0)
    assert pure.distance(pure.describe(p), pure.describe(mirrored)) <= EXACT_TOL["fourier"]
    # a symmetric shape equals its mirror image
    square = np.array([[0, 0], [0, 10], [10, 10], [10, 0]], float)
    assert m.distance(m.describe(square), m.describe(square * [-1, 1])) <= EXACT_TOL["fourier"]


@settings(max_examples=40, deadline=None)
@given(seeds=st.lists(st.integers(0, 2**32 - 1), min_size=1, max_size=6), name=st.sampled_from(NAMES))
def test_distance_is_a_symmetric_nonnegative_dissimilarity(seeds, name):
    m = plugins.matcher(name)
    d = m.describe_many([star(s) * 30 for s in seeds])
    assert d.shape[0] == len(seeds) and np.isfinite(d).all()
    mat = m.distance_matrix(d, d)
    assert mat.shape == (len(seeds), len(seeds))
    assert (mat >= 0).all()
    assert np.allclose(mat, mat.T, rtol=0, atol=1e-12)
    assert np.allclose(np.diag(mat), 0.0, atol=1e-12)
    assert m.distance(d[0], d[-1]) == pytest.approx(mat[0, -1])


def test_describe_many_equals_describe_and_has_fixed_size(matcher):
    outlines = [star(s) * 20 + s for s in range(12)] + [rasterize(star(99) * 50 + 100)]
    many = matcher.describe_many(outlines)
    single = np.stack([matcher.describe(p) for p in outlines])
    assert many.shape == single.shape
    assert np.allclose(many, single, rtol=1e-9, atol=1e-12)
    assert matcher.describe_many([]).shape == (0, many.shape[1])


def test_different_shapes_are_further_apart_than_copies(matcher):
    tri = np.array([[0, 0], [10, 0], [5, 9]], float)
    sq = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)
    lshape = np.array([[0, 0], [10, 0], [10, 3], [3, 3], [3, 12], [0, 12]], float)
    d = matcher.describe_many([tri, sq, lshape, transform(tri, 1.0, 3.0, (5, 5))])
    mat = matcher.distance_matrix(d, d)
    assert mat[0, 3] < 0.2 * min(mat[0, 1], mat[0, 2], mat[1, 2])


@pytest.mark.parametrize("bad", [[[0, 0], [1, 1]], [[0, 0], [1, np.nan], [2, 3]], [[0, 0], [1, np.inf], [2, 3]]])
def test_degenerate_input_raises_contour_error(matcher, bad):
    with pytest.raises(ContourError):
        matcher.describe(bad)
    with pytest.raises(ContourError, match=r"\[1\]"):
        matcher.describe_many([star(1), np.array(bad, float)])


def test_zero_size_outline_raises(matcher):
    with pytest.raises(ContourError):
        matcher.describe([[2, 2], [2, 2], [2, 2]])


def test_options_and_descriptor_shapes_are_validated():
    with pytest.raises(InputError, match="samples"):
        plugins.matcher("fourier", samples=16)
    with pytest.raises(InputError, match="harmonics"):
        plugins.matcher("centroid-distance", harmonics=0)
    with pytest.raises(InputError, match="mirror_terms"):
        plugins.matcher("fourier", mirror_terms=-1)
    m = plugins.matcher("fourier", harmonics=10, mirror_terms=0)
    assert m.describe(star(1)).shape == (10,)
    with pytest.raises(InputError, match="lengths differ"):
        m.distance_matrix(np.zeros((2, 10)), np.zeros((2, 11)))
    with pytest.raises(InputError, match="NaN"):
        m.distance_matrix(np.full((1, 10), np.nan), np.zeros((1, 10)))


def test_hu_distance_is_opencv_i2_on_the_terms_opencv_keeps():
    from sbplan_matchers.hu_moments import HU_EPS

    a = np.array([[0, 0], [40, 0], [40, 10], [10, 10], [10, 60], [0, 60]], np.float32)
    b = np.array([[0, 0], [45, 0], [45, 14], [14, 14], [14, 55], [0, 55]], np.float32)
    ha, hb = (cv2.HuMoments(cv2.moments(p))[:, 0] for p in (a, b))
    both = (np.abs(ha) > HU_EPS) & (np.abs(hb) > HU_EPS)
    assert (np.sign(ha[both]) == np.sign(hb[both])).all() and not both.all()  # the case documented
    m = plugins.matcher("hu-moments")
    da, db = m.describe(a), m.describe(b)
    expected = cv2.matchShapes(a, b, cv2.CONTOURS_MATCH_I2, 0)
    assert np.abs(da - db)[both].sum() == pytest.approx(expected, rel=1e-5)
    assert m.distance(da, db) >= expected


def test_as_descriptors_checks_what_distance_matrix_gets():
    from sbplan.model import as_descriptors

    assert as_descriptors([1, 2, 3]).shape == (1, 3)
    out = as_descriptors(np.arange(6).reshape(2, 3))
    assert out.dtype == np.float64 and out.shape == (2, 3)
    for bad, message in ((np.zeros((2, 2, 2)), "shape"), ([[1.0, np.inf]], "NaN or infinite"), ([["x"]], "numbers")):
        with pytest.raises(InputError, match=message):
            as_descriptors(bad, name="a")


def _fourier_descriptors_numpy(outlines, *, samples=128, harmonics=20, mirror_terms=4):
    """The descriptors as numpy expressions: what the compiled loop replaced, kept as its reference."""
    from sbplan.polygons import resample_complex
    from sbplan_matchers.fourier import _coefficients, _descriptor_plan

    h, gather = _descriptor_plan(harmonics, mirror_terms, samples)
    z = resample_complex(outlines, samples)
    m = len(z)
    if m == 0:
        return np.zeros((0, harmonics + mirror_terms))
    c = _coefficients(z, gather, samples if samples & (samples - 1) else 0)
    mag = np.abs(c)
    a1 = mag[:, 0]
    if not a1.min() > 1e-12 * mag.max():
        degenerate = ~(a1 > 1e-12 * mag.max(axis=1))
        if degenerate.any():
            raise ContourError(f"outlines[{int(np.flatnonzero(degenerate)[0])}]: degenerate outline (no "
                               "first harmonic), it has no Fourier descriptor")
    out = np.empty((m, h + mirror_terms))
    np.divide(mag[:, 1:h + 1], a1[:, None], out=out[:, :h])
    if mirror_terms == 0:
        return out
    c1 = c[:, :1]
    q = c[:, h + 1:h + 1 + mirror_terms] * c[:, h + 1 + mirror_terms:] / (c1 * c1)
    qmag = np.abs(q)
    chir = out[:, h:]
    chir[...] = 0.0
    np.divide(q.imag, np.sqrt(qmag), out=chir, where=qmag > 0)
    return out


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), count=st.integers(1, 12), samples=st.sampled_from([64, 100, 128]),
       mirror_terms=st.integers(0, 4), flip=st.booleans())
def test_compiled_descriptors_agree_with_numpy(seed, count, samples, mirror_terms, flip):
    # The compiled loop against the numpy expressions it replaced, outlines of both senses.
    from sbplan_matchers.fourier import fourier_descriptors

    rng = np.random.default_rng(seed)
    outlines = []
    for _ in range(count):
        n = int(rng.integers(3, 40))
        t = np.sort(rng.uniform(0, 2 * np.pi, n)) + np.linspace(0, 1e-3, n)
        p = np.c_[np.cos(t), np.sin(t)] * rng.uniform(0.3, 1.0, (n, 1)) * rng.uniform(5, 300) + rng.uniform(-500, 500, 2)
        outlines.append(p[::-1] if flip and rng.random() < 0.5 else p)
    got = fourier_descriptors(outlines, samples=samples, harmonics=16, mirror_terms=mirror_terms)
    want = _fourier_descriptors_numpy(outlines, samples=samples, harmonics=16, mirror_terms=mirror_terms)
    assert np.allclose(got, want, rtol=1e-9, atol=1e-12)
