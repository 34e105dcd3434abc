"""Tests of the height-functions plugin: sbplan's contract suite, the alignment against a plain
reference, the descriptor's maths, and detection with it on the renderer's scenes and maps.

Run after installing the plugin (``pip install ./plugins/sbplan-height-functions``):
``python3 -m pytest plugins/sbplan-height-functions/tests``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sbplan import registry as plugins
from sbplan.errors import ContourError, InputError
from sbplan.testing import MatcherContract, calibrated_pipeline, sample_outlines, tiny_floor  # noqa: F401  (fixtures)
from sbplan_height_functions import (HeightFunctionsMatcher, height_descriptors, mirror_descriptors, segment_weights,
                                     shape_complexity)

#: The sbplan checkout this plugin lives in (its maps/ are the renderer's example floors).
REPO = Path(__file__).resolve().parents[3]


class TestContract(MatcherContract):
    """The class itself against sbplan's matcher contract."""

    stage_class = HeightFunctionsMatcher


class TestContractThroughEntryPoint(MatcherContract):
    """What users get: the stage sbplan's registry found through the entry point."""

    stage_name = "height-functions"
    stage_options = {"points": 40, "mirror": False}


def test_found_through_the_entry_point():
    info = plugins.registry().info("matcher", "height-functions")
    assert info.cls is HeightFunctionsMatcher
    assert info.origin == "sbplan-height-functions"


# -- the alignment -----------------------------------------------------------------------------

def reference_alignment(cost: np.ndarray, reward: float) -> float:
    """The definition, step by step: for every start of B, the best order-keeping one-to-one
    matching of A's points to B's read once round from there; unmatched points free, a match
    ``cost - reward``. O(N^3) plain Python."""
    n = len(cost)
    best = 0.0
    for s in range(n):
        d = [[0.0] * (n + 1) for _ in range(n + 1)]
        for i in range(1, n + 1):
            for j in range(1, n + 1):
                d[i][j] = min(d[i - 1][j], d[i][j - 1], d[i - 1][j - 1] + cost[i - 1][(s + j - 1) % n] - reward)
        best = min(best, d[n][n])
    return best


def test_alignment_is_the_best_over_every_start():
    from sbplan_height_functions import _kernels as k

    rng = np.random.default_rng(7)
    for trial in range(60):
        n = int(rng.integers(5, 13))
        cost = rng.random((n, n)) * rng.uniform(0.2, 2.0)
        if trial % 2:  # a shifted, slightly warped diagonal of cheap matches, as similar shapes give
            shift = rng.integers(n)
            for i in range(n):
                cost[i, (i + shift + rng.integers(-1, 2)) % n] *= 0.05
        reward = float(rng.uniform(0.1, 1.5))
        cost2 = np.ascontiguousarray(np.concatenate([cost, cost], axis=1))
        scratch = (np.empty((n + 1, 2 * n + 2)), np.empty((n + 1, n + 1), np.int64), np.empty((n + 1, n + 1), np.int64),
                   np.empty(n + 1, np.int64), np.empty(n + 1, np.int64), np.empty(2 * (n + 2), np.int64))
        expected = reference_alignment(cost.tolist(), reward)
        for step in (1, 2, 3, 8, n):
            got = k.circular_alignment(cost2, reward, step, *scratch)
            assert got == pytest.approx(expected, abs=1e-9), (trial, n, step)


def reference_distance(m: HeightFunctionsMatcher, da: np.ndarray, db: np.ndarray) -> float:
    """The documented distance from two descriptors, with :func:`reference_alignment`."""
    n, n_seg = m.points, m.points // m.segment
    w = segment_weights(m.points, m.segment, m.sigma)
    fa = da[:-1].reshape(n, n_seg) * w
    fb = db[:-1].reshape(n, n_seg) * w
    best = 0.0
    for other in ([fb, mirror_descriptors(fb[None])[0]] if m.mirror else [fb]):
        cost = np.abs(fa[:, None, :] - other[None, :, :]).sum(axis=2)
        best = min(best, reference_alignment(cost.tolist(), 2 * m.skip_cost))
    d = (2 * n * m.skip_cost + best) / n
    return d / (m.offset + max(da[-1], db[-1])) if m.normalize else d


@pytest.mark.parametrize("options", [{}, {"mirror": False}, {"normalize": False, "sigma": 0.5, "skip_cost": 0.3}])
def test_distance_is_the_documented_one(options):
    m = HeightFunctionsMatcher(points=20, **options)
    shapes = sample_outlines()
    desc = m.describe_many([shapes[k] for k in ("flag", "ell", "blob", "thin-triangle")])
    got = m.distance_matrix(desc, desc)
    for a in range(len(desc)):
        for b in range(a + 1, len(desc)):
            assert got[a, b] == pytest.approx(reference_distance(m, desc[a], desc[b]), rel=1e-9, abs=1e-12)


# -- the descriptor ----------------------------------------------------------------------------

def test_descriptor_layout_and_range():
    m = HeightFunctionsMatcher()
    d = m.describe(sample_outlines()["flag"])
    assert d.shape == (m.points * (m.points // m.segment) + 1,) == (m.size,)
    f = d[:-1].reshape(m.points, -1)
    assert np.abs(f).max() <= 1.0
    # segment 0 holds the point and its neighbours, whose heights are 0 or tiny on a straight edge
    assert np.abs(f[:, 0]).mean() < np.abs(f[:, 1:]).mean()


def test_a_circle_is_the_simplest_shape():
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    circle = np.c_[50 * np.cos(t), 50 * np.sin(t)]
    s = sample_outlines()
    c = shape_complexity(height_descriptors([circle, s["square"], s["flag"], s["ell"]]))
    assert c[0] < 0.01 < c[1]
    assert c[0] < c[1] < c[3]  # circle, square, the L: more parts, more change along the outline


def test_mirror_images_match_only_with_mirror():
    flag = sample_outlines()["flag"]
    mirrored = flag * [-1.0, 1.0]
    with_mirror = HeightFunctionsMatcher()
    assert with_mirror.distance(with_mirror.describe(flag), with_mirror.describe(mirrored)) < 1e-9
    without = HeightFunctionsMatcher(mirror=False)
    assert without.distance(without.describe(flag), without.describe(mirrored)) > without.default_threshold
    # the mirror descriptor is what describing the mirror image gives, up to the start point
    d = height_descriptors([flag, mirrored[::-1]])
    m = mirror_descriptors(d[:1])[0]
    assert min(np.abs(np.roll(m, r, axis=0) - d[1]).max() for r in range(len(m))) < 1e-9


def test_bad_options_and_outlines():
    for bad in ({"points": 52}, {"segment": 4}, {"points": 10}, {"sigma": 0}, {"skip_cost": -1}, {"offset": 0},
                {"mirror": "yes"}, {"points": 50.0}):
        with pytest.raises(InputError):
            HeightFunctionsMatcher(**bad)
    with pytest.raises(InputError, match="points"):
        HeightFunctionsMatcher.from_strings(["points=many"])
    m = HeightFunctionsMatcher()
    with pytest.raises(ContourError):
        m.describe([[0, 0], [1, 1]])
    with pytest.raises(ContourError, match="zero-length"):
        m.describe([[2, 2], [2, 2], [2, 2]])
    with pytest.raises(InputError, match="descriptor lengths"):
        m.distance_matrix(np.zeros((1, 8)), np.zeros((1, 8)))
    with pytest.raises(InputError, match="NaN"):
        m.distance_matrix(np.full((1, m.size), np.nan), np.zeros((1, m.size)))


def test_without_numba_a_readable_error(monkeypatch):
    import sys

    from sbplan.errors import PluginError

    m = HeightFunctionsMatcher()
    d = m.describe_many(list(sample_outlines().values())[:2])
    import sbplan_height_functions

    monkeypatch.delitem(sys.modules, "sbplan_height_functions._kernels", raising=False)
    monkeypatch.delattr(sbplan_height_functions, "_kernels", raising=False)
    monkeypatch.setitem(sys.modules, "numba", None)  # what an installation without numba imports
    with pytest.raises(PluginError, match="needs numba"):
        m.distance_matrix(d, d)
    assert m.describe(sample_outlines()["flag"]).shape == (m.size,)  # describing needs no numba


# -- in the detection pipeline -----------------------------------------------------------------

def test_detection_with_this_matcher(calibrated_pipeline):
    detection = calibrated_pipeline.detect(matcher="height-functions")
    assert detection.stages["matcher"] == "height-functions"
    assert calibrated_pipeline.cell_errors(detection) == 0
    assert detection.occupied.any()


def _f1(cal, scene, truth, **stages) -> float:
    from sbplan.detection import Detector
    from sbplan.bench.evaluation import score_cells

    return score_cells(Detector(cal, **stages)(scene).occupied, truth).f1


@pytest.mark.parametrize("condition", ["clean", "shadows"])
def test_f1_unchanged_on_the_renderers_conditions(condition):
    from sbplan.calibration import calibrate
    from sbplan.bench.evaluation import condition_scenes

    scenes = list(condition_scenes(condition, scenes=2, size=(800, 600), grid=(8, 5), seed=4))
    cal = calibrate(scenes[0][0])
    cal_hf = calibrate(scenes[0][0], matcher="height-functions")
    for _, scene, truth in scenes:
        default = _f1(cal, scene, truth.cells)
        assert _f1(cal, scene, truth.cells, matcher="height-functions") == default
        assert _f1(cal_hf, scene, truth.cells) == default


@pytest.mark.parametrize("name", ["paper-8x6", "adverse-lighting"])
def test_f1_unchanged_on_the_example_maps(name):
    from sbplan.calibration import calibrate
    from sbplan.imageio import load_image
    from sbplan.synth.truth import GroundTruth

    folder = REPO / "maps" / name
    if not folder.is_dir():
        pytest.skip(f"{folder} is not here (the plugin's tests run from an sbplan checkout)")
    reference = load_image(folder / "reference.png")
    cal = calibrate(reference)
    cal_hf = calibrate(reference, matcher="height-functions")
    for scene_file in sorted(folder.glob("scene-*.png")):
        truth = GroundTruth.from_json(scene_file.with_suffix(".json")).cells
        scene = load_image(scene_file)
        default = _f1(cal, scene, truth)
        assert _f1(cal, scene, truth, matcher="height-functions") == default
        assert _f1(cal_hf, scene, truth) == default
