"""The contract checks of every stage kind as plain functions (no pytest needed): each raises
``AssertionError`` naming the stage on the first violation; :func:`check_stage` runs a kind's
whole contract. The shapes and pictures they use are made here with numpy and OpenCV."""

from __future__ import annotations

from typing import Any, Callable

import cv2
import numpy as np
from shapely.geometry import LineString, Point

from .. import registry
from ..contours import FREEMAN_STEPS, Contour
from ..contracts import (Binarizer, ContourApproximator, ContourExtractor, DescriptorMatcher, FootprintRefiner,
                         OccupancyMapper,
                         Planner, Stage)
from ..detection.bands import RowBands
from ..detection.grid import fit_grid
from ..errors import InputError, PlanningError
from ..planning import PlanningMap, Problem
from ..polygons import signed_area
from .pipeline import make_tiny_floor

# -- shapes and pictures the checks use ---------------------------------------------------------

def _rotate(points: np.ndarray, degrees: float) -> np.ndarray:
    a = np.deg2rad(degrees)
    c, s = np.cos(a), np.sin(a)
    return points @ np.array([[c, -s], [s, c]]).T


def sample_outlines() -> dict[str, np.ndarray]:
    """Closed outlines ``(x, y)`` (N, 2) float64, counter-clockwise as displayed, about 60 px big.

    ``flag`` (asymmetric, the default floor symbol's shape), ``square``, ``thin-triangle``,
    ``circle`` (64 vertices), ``ell`` (an L), ``blob`` (a smooth asymmetric outline of 90 points).
    """
    flag = np.array([[0, 0], [0, 1], [0.3, 1], [0.3, 0.6], [1, 0.6], [1, 0.35], [0.6, 0.35], [0.6, 0]], float)
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    u = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    r = 1 + 0.25 * np.cos(2 * u) + 0.15 * np.sin(3 * u + 0.4)
    shapes = {
        "flag": flag * 60,
        "square": np.array([[0, 0], [0, 1], [1, 1], [1, 0]], float) * 60,
        "thin-triangle": np.array([[0, 0], [30, 80], [45, 0]], float)[::-1],
        "circle": np.c_[np.cos(t), -np.sin(t)] * 30,
        "ell": np.array([[0, 0], [0, 1], [1, 1], [1, 0.8], [0.25, 0.8], [0.25, 0]], float) * 60,
        "blob": np.c_[r * np.cos(u), -r * np.sin(u)] * 30,
    }
    return {k: _ccw(v) for k, v in shapes.items()}


def _ccw(p: np.ndarray) -> np.ndarray:
    return p if signed_area(p) > 0 else p[::-1].copy()


def _mask_with(*rects: tuple[int, int, int, int], shape=(40, 50), holes=()) -> np.ndarray:
    """Bool mask (H, W) with filled rectangles ``(x0, y0, x1, y1)`` (inclusive) minus holes."""
    m = np.zeros(shape, bool)
    for x0, y0, x1, y1 in rects:
        m[y0:y1 + 1, x0:x1 + 1] = True
    for x0, y0, x1, y1 in holes:
        m[y0:y1 + 1, x0:x1 + 1] = False
    return m


def _random_mask(seed: int, shape=(48, 64)) -> np.ndarray:
    """Blobs with holes: smoothed noise thresholded, so regions are of a few to a few hundred pixels."""
    rng = np.random.default_rng(seed)
    noise = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), 1.6)
    return noise > 0.15


def _rect_contour(x0: int, y0: int, x1: int, y1: int) -> Contour:
    """The outer boundary of a filled rectangle, traversed counter-clockwise as displayed."""
    left = [(x0, y) for y in range(y0, y1)]
    bottom = [(x, y1) for x in range(x0, x1)]
    right = [(x1, y) for y in range(y1, y0, -1)]
    top = [(x, y0) for x in range(x1, x0, -1)]
    pts = np.array(left + bottom + right + top, np.int64)
    steps = np.roll(pts, -1, axis=0) - pts
    chain = np.array([int(np.flatnonzero((FREEMAN_STEPS == s).all(1))[0]) for s in steps], np.uint8)
    return Contour(pts, False, 1, chain, -1)


# -- contract checks ------------------------------------------------------------------------------
# Each check takes a stage instance and raises AssertionError with a message saying what broke.

def check_declaration(stage: Stage) -> None:
    """The class has a kind, a name, a one-line description, and options with help texts that
    survive a round trip through ``config()`` and ``from_strings``."""
    cls = type(stage)
    assert isinstance(stage, Stage) and cls.kind in registry.KINDS, f"{cls.__qualname__}: not a stage contract subclass"
    assert isinstance(cls.name, str) and cls.name and cls.name == cls.name.strip(), f"{cls.__qualname__}: needs a name"
    assert " " not in cls.name, f"{cls.kind} name {cls.name!r}: names are typed on the command line, no spaces"
    desc = cls.description or (cls.__doc__ or "").strip()
    assert desc and "\n" not in cls.description, f"{cls.kind} {cls.name!r}: needs a one-line description"
    config = stage.config()
    for opt in cls.options():
        assert opt.help, f"{cls.kind} {cls.name!r}: option {opt.name!r} has no help text"
    assert cls(**config).config() == config, f"{cls.kind} {cls.name!r}: cls(**config()) does not rebuild the stage"
    simple = {k: str(v) for k, v in config.items() if isinstance(v, (bool, int, float, str))}
    assert cls.from_strings(simple).config() == {**config}, \
        f"{cls.kind} {cls.name!r}: from_strings(key=str(value)) does not give back the same options"
    try:
        cls.from_strings(["no_such_option_xyz=1"])
    except InputError:
        pass
    else:  # pragma: no cover - Stage.from_strings always raises
        raise AssertionError(f"{cls.kind} {cls.name!r}: an unknown option was accepted")


def check_registered(stage: Stage) -> None:
    """The stage is found by name in the process-wide registry, as the same class."""
    info = registry.registry().info(stage.kind, stage.name)
    assert info.cls is type(stage), f"{stage.kind} {stage.name!r}: the registry holds {info.cls!r}"


# binarizer

def check_binarizer_output(stage: Binarizer) -> None:
    """``binarize`` returns a bool (H, W) mask and does not modify its input."""
    floor = make_tiny_floor()
    gray = np.array(floor.reference)
    out = stage.binarize(gray)
    assert isinstance(out, np.ndarray) and out.dtype == bool and out.shape == gray.shape, \
        f"binarizer {stage.name!r}: expected a bool array of shape {gray.shape}, got {getattr(out, 'dtype', type(out))} {getattr(out, 'shape', '')}"
    assert np.array_equal(gray, floor.reference), f"binarizer {stage.name!r}: modified its input"


def check_binarizer_finds_ink(stage: Binarizer) -> None:
    """Dark printed symbols on a lighter floor are foreground, the floor is not."""
    floor = make_tiny_floor()
    gray = floor.reference
    out = stage.binarize(np.array(gray))
    ink, bare = gray < 80, gray > 160
    assert ink.any() and bare.any()
    assert out[ink].mean() > 0.9, f"binarizer {stage.name!r}: only {out[ink].mean():.0%} of the ink is foreground"
    assert out[bare].mean() < 0.05, f"binarizer {stage.name!r}: {out[bare].mean():.0%} of the bare floor is foreground"


def check_binarizer_bands(stage: Binarizer) -> None:
    """``binarize_bands`` gives the stacked mask of the bands: what ``binarize`` finds in them,
    away from the band edges (where a filter may see the band's end instead of the next rows),
    and nothing in the separator rows."""
    floor = make_tiny_floor()
    gray = np.array(floor.reference)
    h = gray.shape[0]
    bands = RowBands([(10, h // 2 - 10), (h // 2 + 4, h - 6)], gray.shape)
    out = stage.binarize_bands(gray, bands)
    assert isinstance(out, np.ndarray) and out.dtype == bool and out.shape == bands.stacked_shape, \
        f"binarizer {stage.name!r}: binarize_bands gave {getattr(out, 'dtype', type(out))} " \
        f"{getattr(out, 'shape', '')}, expected bool {bands.stacked_shape}"
    whole = bands.stack(stage.binarize(gray), fill=False)
    inner = np.zeros(bands.stacked_shape[0], bool)
    for a, b, o in zip(bands.starts.tolist(), bands.stops.tolist(), bands.offsets.tolist()):
        inner[o + 8:o + b - a - 8] = True
    separators = np.ones(bands.stacked_shape[0], bool)
    for a, b, o in zip(bands.starts.tolist(), bands.stops.tolist(), bands.offsets.tolist()):
        separators[o:o + b - a] = False
    assert not out[separators].any(), f"binarizer {stage.name!r}: binarize_bands put ink in the separator rows"
    differ = float((out[inner] != whole[inner]).mean())
    assert differ == 0.0, f"binarizer {stage.name!r}: binarize_bands differs from binarize on {differ:.1%} of the band pixels"
    assert np.array_equal(gray, floor.reference), f"binarizer {stage.name!r}: modified its input"


def check_binarizer_locality(stage: Binarizer) -> None:
    """What ``locality()`` promises holds (nothing to check when it returns None): on crops of the
    tiny floor's scene (a shadow over it) whose corners lie on multiples of ``step``, ``binarize``
    gives what it gives on the whole image farther than ``reach`` pixels from every side of the
    crop that is not the image's."""
    promise = stage.locality()
    if promise is None:
        return
    reach, step = promise
    assert isinstance(reach, (int, np.integer)) and isinstance(step, (int, np.integer)) and reach >= 0 and step >= 1, \
        f"binarizer {stage.name!r}: locality() gave {promise!r}, expected (reach >= 0, step >= 1) integers"
    scene = np.array(make_tiny_floor(condition="shadows").scene)
    h, w = scene.shape[0] // step * step, scene.shape[1] // step * step
    gray = scene[:h, :w]
    whole = stage.binarize(gray)
    for fx0, fy0, fx1, fy1 in ((0.1, 0.2, 0.8, 0.9), (0.0, 0.3, 0.6, 1.0), (0.4, 0.0, 1.0, 0.7)):
        x0, x1 = int(fx0 * w) // step * step, int(fx1 * w) // step * step
        y0, y1 = int(fy0 * h) // step * step, int(fy1 * h) // step * step
        zx0, zy0 = (x0 + reach if x0 else 0), (y0 + reach if y0 else 0)
        zx1, zy1 = (x1 - reach if x1 < w else w), (y1 - reach if y1 < h else h)
        if zx1 <= zx0 or zy1 <= zy0:
            continue  # a reach as large as the crop promises nothing here
        crop = stage.binarize(gray[y0:y1, x0:x1])
        differ = int((crop[zy0 - y0:zy1 - y0, zx0 - x0:zx1 - x0] != whole[zy0:zy1, zx0:zx1]).sum())
        assert differ == 0, (f"binarizer {stage.name!r}: promises a reach of {reach} px (step {step}), but a crop "
                             f"({x0}, {y0}, {x1}, {y1}) differs from the whole image at {differ} pixels that far "
                             "inside it")


# extractor

def _closed_steps_ok(c: Contour) -> bool:
    if len(c.points) == 1:
        return True
    steps = np.roll(c.points, -1, axis=0) - c.points
    return bool((np.abs(steps).max(axis=1) == 1).all())


def check_extractor_rectangle(stage: ContourExtractor) -> None:
    """A filled rectangle gives one counter-clockwise outer contour of its border pixels."""
    mask = _mask_with((5, 7, 24, 30))
    contours = stage.extract(mask)
    assert len(contours) == 1, f"extractor {stage.name!r}: a filled rectangle gave {len(contours)} contours"
    c = contours[0]
    assert isinstance(c, Contour) and not c.is_hole and c.orientation == 1, \
        f"extractor {stage.name!r}: expected an outer contour with orientation +1"
    pts = np.asarray(c.points)
    assert pts.ndim == 2 and pts.shape[1] == 2 and np.issubdtype(pts.dtype, np.integer), \
        f"extractor {stage.name!r}: points must be an integer (N, 2) array"
    border = {(x, y) for x in range(5, 25) for y in (7, 30)} | {(x, y) for y in range(7, 31) for x in (5, 24)}
    assert set(map(tuple, pts.tolist())) == border and len(pts) == len(border), \
        f"extractor {stage.name!r}: the rectangle's contour is not exactly its {len(border)} border pixels"
    assert _closed_steps_ok(c), f"extractor {stage.name!r}: the contour is not a closed 8-connected chain"
    assert signed_area(pts) > 0, f"extractor {stage.name!r}: the outer contour is not counter-clockwise as displayed"


def check_extractor_hole(stage: ContourExtractor) -> None:
    """A ring gives an outer contour and a clockwise hole whose parent is that outer contour."""
    mask = _mask_with((4, 4, 30, 28), holes=[(10, 10, 20, 19)])
    contours = stage.extract(mask)
    outer = [i for i, c in enumerate(contours) if not c.is_hole]
    holes = [i for i, c in enumerate(contours) if c.is_hole]
    assert len(outer) == 1 and len(holes) == 1, \
        f"extractor {stage.name!r}: a ring gave {len(outer)} outer contours and {len(holes)} holes"
    h = contours[holes[0]]
    assert h.orientation == -1, f"extractor {stage.name!r}: holes run clockwise (orientation -1)"
    assert h.parent == outer[0], f"extractor {stage.name!r}: the hole's parent is {h.parent}, expected {outer[0]}"
    assert _closed_steps_ok(h) and signed_area(h.points) < 0, \
        f"extractor {stage.name!r}: the hole is not a closed clockwise chain"


def check_extractor_counts(stage: ContourExtractor, *, seeds=(1, 2, 3)) -> None:
    """On random masks: one outer contour per 8-connected region and one hole per 4-connected
    background region that does not touch the border; every contour closed, chains consistent."""
    for seed in seeds:
        mask = _random_mask(seed)
        n_regions = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)[0] - 1
        n_bg, lab = cv2.connectedComponents((~mask).astype(np.uint8), connectivity=4)
        edge = set(np.unique(np.r_[lab[0], lab[-1], lab[:, 0], lab[:, -1]]).tolist())
        n_holes = len(set(range(1, n_bg)) - edge)
        contours = stage.extract(mask)
        outer = sum(not c.is_hole for c in contours)
        holes = sum(c.is_hole for c in contours)
        assert (outer, holes) == (n_regions, n_holes), \
            f"extractor {stage.name!r}: mask seed {seed}: {outer} outer contours and {holes} holes, expected {n_regions} and {n_holes}"
        for i, c in enumerate(contours):
            assert _closed_steps_ok(c), f"extractor {stage.name!r}: mask seed {seed}: contour {i} is not closed"
            p = np.asarray(c.points)
            assert mask[p[:, 1], p[:, 0]].all(), \
                f"extractor {stage.name!r}: mask seed {seed}: contour {i} runs over background pixels"
            if len(c.chain):
                steps = np.roll(p, -1, axis=0) - p
                assert np.array_equal(FREEMAN_STEPS[c.chain], steps), \
                    f"extractor {stage.name!r}: mask seed {seed}: contour {i}'s chain does not match its points"
            assert -1 <= c.parent < len(contours), f"extractor {stage.name!r}: contour {i} has parent {c.parent}"


def check_extractor_empty(stage: ContourExtractor) -> None:
    """An empty mask has no contours."""
    assert list(stage.extract(np.zeros((20, 30), bool))) == [], f"extractor {stage.name!r}: contours in an empty mask"


def check_extractor_outer(stage: ContourExtractor, *, seeds=(1, 2, 3)) -> None:
    """``extract_outer`` gives the outer contours of ``extract``, same points, same order."""
    for seed in seeds:
        mask = _random_mask(seed)
        expected = [c for c in stage.extract(mask) if not c.is_hole]
        got = stage.extract_outer(mask)
        assert len(got) == len(expected), \
            f"extractor {stage.name!r}: mask seed {seed}: extract_outer gave {len(got)} contours, extract {len(expected)} outer ones"
        for i, (g, e) in enumerate(zip(got, expected)):
            assert not g.is_hole and np.array_equal(np.asarray(g.points), np.asarray(e.points)), \
                f"extractor {stage.name!r}: mask seed {seed}: extract_outer's contour {i} differs from extract's"


# approximator

def check_approximator_many(stage: ContourApproximator, *, seed: int = 2) -> None:
    """``approximate_many`` gives what ``approximate`` gives for each contour, in order."""
    ext = registry.extractor("opencv")
    contours = [c for c in ext.extract(_random_mask(seed)) if len(c.points) >= 8][:12]
    contours.append(_rect_contour(3, 4, 40, 25))
    many = stage.approximate_many(contours)
    assert len(many) == len(contours), f"approximator {stage.name!r}: approximate_many gave {len(many)} polygons for {len(contours)} contours"
    for i, (c, poly) in enumerate(zip(contours, many)):
        one = np.asarray(stage.approximate(c), float)
        assert np.allclose(np.asarray(poly, float), one), \
            f"approximator {stage.name!r}: approximate_many's polygon {i} differs from approximate's"
    assert len(stage.approximate_many([])) == 0, f"approximator {stage.name!r}: approximate_many([]) is not empty"


def check_approximator_rectangle(stage: ContourApproximator) -> None:
    """A rectangle's contour becomes a polygon of about its area, in the same traversal sense."""
    c = _rect_contour(3, 4, 40, 25)
    poly = np.asarray(stage.approximate(c))
    assert poly.ndim == 2 and poly.shape[1] == 2 and len(poly) >= 3 and np.isfinite(poly).all(), \
        f"approximator {stage.name!r}: expected finite (M >= 3, 2) vertices, got shape {poly.shape}"
    area = abs(signed_area(poly))
    assert abs(area - 37 * 21) <= 0.1 * 37 * 21, f"approximator {stage.name!r}: area {area:.0f}, the contour's is {37 * 21}"
    assert signed_area(poly) > 0, f"approximator {stage.name!r}: the polygon does not keep the contour's traversal sense"


def check_approximator_near_contour(stage: ContourApproximator, *, seeds=(1, 2)) -> None:
    """On real contours every vertex lies within 2 px of the contour, and the area of contours
    enclosing at least 200 px^2 is kept within 15 %."""
    ext = registry.extractor("opencv")
    for seed in seeds:
        contours = [c for c in ext.extract(_random_mask(seed)) if len(c.points) >= 20]
        for c in contours[:12]:
            poly = np.asarray(stage.approximate(c), float)
            assert poly.ndim == 2 and poly.shape[1] == 2 and np.isfinite(poly).all(), \
                f"approximator {stage.name!r}: bad output shape {poly.shape}"
            ring = LineString(np.vstack([c.points, c.points[:1]]).astype(float))
            far = max(ring.distance(Point(v)) for v in poly)
            assert far <= 2.0, f"approximator {stage.name!r}: a vertex lies {far:.1f} px from the contour"
            a0, a1 = abs(signed_area(c.points)), abs(signed_area(poly))
            if a0 >= 200:
                assert abs(a1 - a0) <= 0.15 * a0, f"approximator {stage.name!r}: polygon area {a1:.0f} vs contour {a0:.0f}"


# matcher

def _descriptor_ok(stage: DescriptorMatcher, d: Any, k: int | None, what: str) -> int:
    d = np.asarray(d)
    assert d.ndim == 1 and d.dtype.kind == "f" and np.isfinite(d).all(), \
        f"matcher {stage.name!r}: describe({what}) is not a finite 1-D float vector ({d.dtype}, {d.shape})"
    assert k is None or len(d) == k, f"matcher {stage.name!r}: describe({what}) has {len(d)} entries, others {k}"
    return len(d)


def check_matcher_descriptors(stage: DescriptorMatcher) -> None:
    """``describe`` returns a finite vector of one fixed size; ``describe_many`` agrees with it."""
    shapes = sample_outlines()
    k = None
    for name, p in shapes.items():
        k = _descriptor_ok(stage, stage.describe(p), k, name)
    many = np.asarray(stage.describe_many(list(shapes.values())))
    assert many.shape == (len(shapes), k), f"matcher {stage.name!r}: describe_many gave shape {many.shape}"
    one = np.stack([stage.describe(p) for p in shapes.values()])
    assert np.allclose(many, one, rtol=1e-9, atol=1e-12), f"matcher {stage.name!r}: describe_many differs from describe"
    assert np.asarray(stage.describe_many([])).shape == (0, k), f"matcher {stage.name!r}: describe_many([]) is not (0, K)"
    t = stage.default_threshold
    assert isinstance(t, (int, float)) and np.isfinite(t) and t > 0, f"matcher {stage.name!r}: default_threshold {t!r}"


def check_matcher_distances(stage: DescriptorMatcher) -> None:
    """Distances are >= 0, symmetric, zero on identical descriptors; ``distance_matrix`` is (n, m)
    and agrees with ``distance``."""
    shapes = list(sample_outlines().values())
    d = np.asarray(stage.describe_many(shapes))
    mat = np.asarray(stage.distance_matrix(d, d[:3]))
    assert mat.shape == (len(d), 3), f"matcher {stage.name!r}: distance_matrix gave shape {mat.shape}"
    full = np.asarray(stage.distance_matrix(d, d))
    assert np.isfinite(full).all() and (full >= 0).all(), f"matcher {stage.name!r}: negative or non-finite distances"
    assert np.allclose(full, full.T, rtol=1e-9, atol=1e-12), f"matcher {stage.name!r}: distances are not symmetric"
    assert np.allclose(np.diag(full), 0, atol=1e-9), f"matcher {stage.name!r}: distance to itself is not 0"
    assert np.allclose(mat, full[:, :3], rtol=1e-9, atol=1e-12), f"matcher {stage.name!r}: distance_matrix is not consistent"
    assert abs(stage.distance(d[0], d[1]) - full[0, 1]) <= 1e-9 * max(1.0, full[0, 1]), \
        f"matcher {stage.name!r}: distance() differs from distance_matrix()"


def check_matcher_invariance(stage: DescriptorMatcher) -> None:
    """Translation, rotation, scale, start point and traversal direction move an outline (the flag,
    the thin triangle, the blob) by less than a third of ``default_threshold``."""
    limit = stage.default_threshold / 3
    shapes = sample_outlines()
    for name in ("flag", "thin-triangle", "blob"):
        base = shapes[name]
        variants = {
            "translated": base + [123.0, -45.0],
            "rotated 37 deg": _rotate(base, 37.0),
            "rotated 90 deg": _rotate(base, 90.0),
            "scaled x2.5": base * 2.5,
            "start point moved": np.roll(base, 2, axis=0),
            "reversed": base[::-1].copy(),
        }
        ref = stage.describe(base)
        for what, p in variants.items():
            dist = stage.distance(ref, stage.describe(p))
            assert dist < limit, \
                f"matcher {stage.name!r}: the {name} {what} is at distance {dist:.4g} (limit {limit:.4g})"


def check_matcher_discriminates(stage: DescriptorMatcher) -> None:
    """Clearly different shapes are farther apart than ``default_threshold``."""
    s = sample_outlines()
    ref = stage.describe(s["flag"])
    for other in ("square", "thin-triangle", "circle"):
        dist = stage.distance(ref, stage.describe(s[other]))
        assert dist > stage.default_threshold, \
            f"matcher {stage.name!r}: flag vs {other} at {dist:.4g}, not above default_threshold {stage.default_threshold}"


# mapper

def _grid(rows: int = 3, cols: int = 4, pitch: float = 40.0, origin=(30.0, 25.0)):
    c, r = np.meshgrid(np.arange(cols), np.arange(rows))
    centres = np.c_[origin[0] + pitch * c.ravel(), origin[1] + pitch * r.ravel()]
    return fit_grid(centres)


def check_mapper(stage: OccupancyMapper) -> None:
    """No occupied cell: all white; an occupied cell is black at its centre and nowhere near the
    others; more occupied cells, more black; values are only 0 and 255."""
    grid = _grid()
    shape = (140, 190)
    centres = grid.centres_px.reshape(-1, 2)
    none = np.zeros(grid.shape, bool)
    img = np.asarray(stage.occupancy_image(grid, none, shape))
    assert img.shape == shape and img.dtype == np.uint8, f"mapper {stage.name!r}: got {img.dtype} {img.shape}"
    assert (img == 255).all(), f"mapper {stage.name!r}: black pixels with no occupied cell"
    one = none.copy()
    one[1, 2] = True
    img = np.asarray(stage.occupancy_image(grid, one, shape))
    assert set(np.unique(img).tolist()) <= {0, 255}, f"mapper {stage.name!r}: values other than 0 and 255"
    px = np.rint(centres).astype(int)
    black = img[px[:, 1], px[:, 0]] == 0
    assert black.tolist() == one.ravel().tolist(), f"mapper {stage.name!r}: black cell centres {black.reshape(grid.shape)}"
    two = one.copy()
    two[0, 0] = True
    img2 = np.asarray(stage.occupancy_image(grid, two, shape))
    assert (img2 == 0).sum() > (img == 0).sum(), f"mapper {stage.name!r}: a second occupied cell added no black"


# footprint

def check_footprint_outlines(stage: FootprintRefiner) -> None:
    """On the tiny floor's scene (its cells detected by the default pipeline): ``prepare`` runs on
    the calibration, ``outlines`` gives closed (K >= 3, 2) float outlines inside the image, that do
    not overlap, and reach every occupied cell (its centre inside an outline or within half a
    pitch of one); none when no cell is occupied; the frame is not changed."""
    from shapely.geometry import Point, Polygon

    from ..detection import Detector
    from .pipeline import make_calibrated_pipeline

    pipeline = make_calibrated_pipeline()
    cal = pipeline.calibration
    floor = make_tiny_floor()
    detector = Detector(cal)
    cells = detector.find_cells(floor.scene)
    occupancy = detector.mapper.occupancy_image(cal.grid, cells.occupied, cells.image_shape)
    prepared = stage.prepare(cal)
    frame = floor.scene.copy()
    outlines = stage.outlines(frame, cells.occupied, occupancy, cal, cells.camera, prepared)
    assert np.array_equal(frame, floor.scene), f"footprint {stage.name!r}: changed the frame"
    assert isinstance(outlines, list), f"footprint {stage.name!r}: outlines() must return a list"
    h, w = cal.image_shape
    polys = []
    for i, o in enumerate(outlines):
        o = np.asarray(o)
        assert o.ndim == 2 and o.shape[1] == 2 and len(o) >= 3 and o.dtype.kind == "f", \
            f"footprint {stage.name!r}: outline {i} is {o.dtype} of shape {o.shape}, expected (K >= 3, 2) floats"
        assert np.isfinite(o).all() and (o >= -1).all() and (o[:, 0] <= w).all() and (o[:, 1] <= h).all(), \
            f"footprint {stage.name!r}: outline {i} leaves the {w} x {h} image"
        polys.append(Polygon(o).buffer(0))
    for i in range(len(polys)):
        for j in range(i + 1, len(polys)):
            overlap = polys[i].intersection(polys[j]).area
            assert overlap <= 1e-6 * max(polys[i].area, polys[j].area, 1.0), \
                f"footprint {stage.name!r}: outlines {i} and {j} overlap by {overlap:.3g} px²"
    reach = 0.5 * float(min(cal.grid.pitch_px))
    for r, c in zip(*np.nonzero(cells.occupied)):
        centre = Point(cal.grid.centres_px[r, c])
        assert any(p.distance(centre) <= reach for p in polys), \
            f"footprint {stage.name!r}: no outline reaches occupied cell ({r}, {c})"
    none = np.zeros_like(cells.occupied)
    empty = np.full(cal.image_shape, 255, np.uint8)
    assert stage.outlines(floor.reference, none, empty, cal, cells.camera, prepared) == [], \
        f"footprint {stage.name!r}: outlines on a floor with no occupied cell"


# planner

def _planning_map(radius: float = 0.3):
    walls = [np.array([[3, 0], [4, 0], [4, 7], [3, 7]], float), np.array([[6, 3], [7, 3], [7, 10], [6, 10]], float)]
    return PlanningMap(walls, robot_radius=radius, bounds=(0, 0, 10, 10))


def check_planner_route(stage: Planner, *, time_limit: float = 2.0) -> None:
    """The route runs from start to goal, stays in bounds and keeps the robot radius from every
    obstacle (to 1e-6 of the map's size), and is no shorter than the straight line."""
    pmap = _planning_map()
    start, goal = np.array([1.0, 1.0]), np.array([9.0, 1.0])
    route = stage.solve(Problem(pmap, start, goal), time_limit=time_limit)
    wp = np.asarray(route.waypoints, float)
    assert wp.ndim == 2 and wp.shape[1] == 2 and len(wp) >= 2, f"planner {stage.name!r}: waypoints of shape {wp.shape}"
    assert np.allclose(wp[0], start) and np.allclose(wp[-1], goal), f"planner {stage.name!r}: route does not join start and goal"
    x0, y0, x1, y1 = pmap.bounds
    assert ((wp >= [x0, y0]) & (wp <= [x1, y1])).all(), f"planner {stage.name!r}: a waypoint is out of bounds"
    line = LineString(wp)
    tol = 1e-6 * pmap.scale
    for i, ob in enumerate(pmap.obstacles):
        clearance = line.distance(ob)
        assert clearance >= pmap.robot_radius - tol, \
            f"planner {stage.name!r}: the route passes {clearance:.4g} from obstacle {i} (robot radius {pmap.robot_radius})"
    assert route.length >= float(np.hypot(*(goal - start))) - 1e-9, f"planner {stage.name!r}: route shorter than the straight line"


def check_planner_rejects_bad_start(stage: Planner, *, time_limit: float = 0.5) -> None:
    """A start inside an obstacle raises a PlanningError (not a crash, not a route)."""
    pmap = _planning_map()
    try:
        stage.solve(Problem(pmap, np.array([3.5, 3.0]), np.array([9.0, 1.0])), time_limit=time_limit)
    except PlanningError:
        return
    raise AssertionError(f"planner {stage.name!r}: planned from a start inside an obstacle")


CHECKS: dict[str, tuple[Callable[[Any], None], ...]] = {
    "binarizer": (check_binarizer_output, check_binarizer_finds_ink, check_binarizer_bands, check_binarizer_locality),
    "extractor": (check_extractor_rectangle, check_extractor_hole, check_extractor_counts, check_extractor_empty,
                  check_extractor_outer),
    "approximator": (check_approximator_rectangle, check_approximator_near_contour, check_approximator_many),
    "matcher": (check_matcher_descriptors, check_matcher_distances, check_matcher_invariance, check_matcher_discriminates),
    "mapper": (check_mapper,),
    "footprint": (check_footprint_outlines,),
    "planner": (check_planner_route, check_planner_rejects_bad_start),
}
"""kind -> the checks of its contract (besides :func:`check_declaration`)."""


def check_stage(stage: Stage) -> None:
    """Run the whole contract of ``stage``'s kind; raises AssertionError on the first violation."""
    check_declaration(stage)
    for check in CHECKS[stage.kind]:
        check(stage)
