"""Symbol ranking: the paper's equations (2)-(4), regularity, confusion margin, and the recommended
symbol working on a rendered floor."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sbplan import registry as plugins
from sbplan.errors import InputError
from sbplan.symbols import rank as R
from sbplan.symbols.noise import NOISE_FAMILIES, noise_set
from sbplan.symbols.raster import symbol_rings


# -- equations (2)-(4) on a hand-computed example -----------------------------------------------
# Three descriptors on a line: A = (0, 0), B = (3, 4), C = (6, 8); d_AB = d_BC = 5, d_AC = 10.
#   row A: [0, 5, 10]  mean 15/3 = 5       variance ((0-5)^2 + 0 + (10-5)^2) / 2 = 25    score 5
#   row B: [5, 0, 5]   mean 10/3           variance ((5/3)^2 + (10/3)^2 + (5/3)^2) / 2 = 25/3
#                                          score (25/3) / (10/3) = 2.5
#   row C: [10, 5, 0]  mean 5              variance 25                                     score 5
HAND = np.array([[0.0, 0.0], [3.0, 4.0], [6.0, 8.0]])


def test_equation_2_distance_matrix_by_hand():
    d = R.distance_matrix(HAND)
    np.testing.assert_allclose(d, [[0, 5, 10], [5, 0, 5], [10, 5, 0]])


def test_equation_2_through_the_fourier_matcher_is_euclidean():
    np.testing.assert_allclose(R.distance_matrix(HAND, "fourier"), R.distance_matrix(HAND))


def test_equation_3_mean_and_variance_by_hand():
    mean, var = R.distance_statistics(R.distance_matrix(HAND))
    np.testing.assert_allclose(mean, [5, 10 / 3, 5])
    np.testing.assert_allclose(var, [25, 25 / 3, 25])


def test_equation_3_uses_the_rows_own_mean_not_the_papers_typo():
    d = R.distance_matrix(HAND)
    _, var = R.distance_statistics(d)
    mean = d.mean(axis=1)
    typo = ((d - mean[None, :]) ** 2).sum(axis=1) / 2  # (d_ij - dbar_j)^2 as printed in the paper
    assert not np.isclose(var[0], typo[0])
    assert np.isclose(var[0], np.var(d[0], ddof=1))


def test_equation_4_score_and_order_by_hand():
    score, order = R.rank_order(R.distance_matrix(HAND))
    np.testing.assert_allclose(score, [5, 2.5, 5])
    assert order.tolist() == [1, 0, 2]


def test_a_symbol_identical_to_all_others_scores_infinite():
    score, order = R.rank_order(np.zeros((3, 3)))
    assert np.isinf(score).all() and order.tolist() == [0, 1, 2]


@pytest.mark.parametrize("bad", [np.zeros((2, 3)), np.zeros((1, 1)), np.array([[0, -1], [-1, 0.0]]),
                                 np.array([[0, np.nan], [np.nan, 0]])])
def test_bad_distance_matrix_names_the_parameter(bad):
    with pytest.raises(InputError, match="distances"):
        R.distance_statistics(bad)


# -- regularity and noise set ---------------------------------------------------------------------
def test_regularity_separates_straight_from_round_outlines():
    reg = {n: R.regularity(symbol_rings(n)) for n in ("square", "triangle", "flag", "circle", "ellipse",
                                                      "ring", "rounded-square")}
    assert reg["square"] > 0.95 and reg["triangle"] > 0.95 and reg["flag"] > 0.95
    assert reg["circle"] < 0.05 and reg["ellipse"] < 0.05 and reg["ring"] < 0.05
    # four straight sides and four quarter circles: in between, close to the straight share 4.8/7.31
    assert 0.55 < reg["rounded-square"] < 0.75


def test_noise_set_is_seeded_and_families_are_independent():
    rings = symbol_rings("flag")
    a = noise_set(rings, seed=3, per_family=4)
    b = noise_set(rings, seed=3, per_family=4)
    assert [f for f, _ in a] == [f for f, _ in b]
    assert all(np.array_equal(x, y) for (_, ra), (_, rb) in zip(a, b) for x, y in zip(ra, rb))
    assert {f for f, _ in a} == set(NOISE_FAMILIES)
    blobs_only = noise_set(rings, seed=3, per_family=4, families="blobs")
    assert all(np.array_equal(x[1][0], y[1][0]) for x, y in zip(blobs_only, [s for s in a if s[0] == "blobs"]))
    assert noise_set(None, seed=3, per_family=4, families=["occluded"]) == []


def test_occluded_copies_hide_part_of_the_symbol():
    from shapely.geometry import Polygon

    rings = symbol_rings("letter-h")
    full = Polygon(rings[0])
    for _, r in noise_set(rings, families="occluded", per_family=6, seed=1):
        part = Polygon(r[0], r[1:])
        # rescaled to the unit box, so compare shapes through their fill of the bounding box
        assert part.is_valid and part.area > 0
        assert not np.isclose(part.area / (np.ptp(r[0], axis=0).prod()), full.area / np.ptp(rings[0], axis=0).prod())


@pytest.mark.parametrize("kwargs, word", [
    (dict(candidates=["flag"]), "candidates"),
    (dict(candidates="flag"), "candidates"),
    (dict(candidates=["flag", "cross"], noise_families="blobs,glare"), "noise_set"),
    (dict(candidates=["flag", "cross"], sizes=[4]), "sizes"),
    (dict(candidates=["flag", "cross"], min_margin=-1), "min_margin"),
    (dict(candidates=["flag", "nope"]), "symbol"),
])
def test_rank_symbols_rejects_bad_input(kwargs, word):
    with pytest.raises(InputError, match=word):
        R.rank_symbols(**kwargs)


# -- the full ranking -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ranking():
    calls = []
    r = R.rank_symbols(progress=lambda done, total, name: calls.append((done, total, name)))
    r.calls = calls
    return r


def test_ranking_covers_the_library_and_reports_progress(ranking):
    names = plugins.symbol_names()
    assert len(names) >= 30
    assert ranking.names == names
    assert [c[0] for c in ranking.calls] == list(range(1, len(names) + 1))
    assert sorted(ranking.order.tolist()) == list(range(len(names)))
    assert np.all(np.diff(ranking.score[ranking.order]) >= 0)
    np.testing.assert_allclose(ranking.distances, ranking.distances.T)


def test_round_shapes_rank_at_the_bottom_for_confusion_margin(ranking):
    m = len(ranking.names)
    rank_of = {row["name"]: row["margin_rank"] for row in ranking.rows()}
    assert rank_of["circle"] > m - 5 and rank_of["ellipse"] > m - 5
    i = ranking.names.index("circle")
    assert ranking.margin[i] < 1 and ranking.nearest_noise[i] == "circles"


def test_recommended_symbol_meets_every_condition(ranking):
    best = ranking.recommended
    assert best is not None
    i = ranking.names.index(best)
    assert ranking.regularity[i] >= 0.5 and ranking.margin[i] >= 2.0
    # it is the first qualifying one of the equation (4) order
    ok = ranking.qualifies()
    assert next(ranking.names[j] for j in ranking.order if ok[j]) == best
    data = json.loads(json.dumps(ranking.to_dict()))
    assert data["recommended"] == best and len(data["candidates"]) == len(ranking.names)


def test_recommended_symbol_is_detected_perfectly_on_clean_scenes(ranking):
    from sbplan.detection import detect
    from sbplan.detection.calibration import calibrate
    from sbplan.synth import AMBIGUOUS, FloorSpec, SceneSpec, render_reference, render_scene

    floor = FloorSpec(width=960, height=720, cols=8, rows=6, symbol=ranking.recommended)
    cal = calibrate(render_reference(floor, seed=0))
    assert cal.symbols_expected == 48
    tp = fp = fn = 0
    for seed in (1, 2, 3):
        img, truth = render_scene(floor, SceneSpec(n_obstacles=3, condition="clean"), seed=seed)
        occ = detect(img, cal).occupied
        keep = truth.cells != AMBIGUOUS
        tp += int((occ & truth.occupied & keep).sum())
        fp += int((occ & ~truth.occupied & keep).sum())
        fn += int((~occ & truth.occupied & keep).sum())
    assert tp > 0
    assert 2 * tp / (2 * tp + fp + fn) == 1.0


def test_ranking_works_with_other_matchers_and_given_polygons():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    tee = np.array([[0, 0], [1, 0], [1, 0.3], [0.65, 0.3], [0.65, 1], [0.35, 1], [0.35, 0.3], [0, 0.3]])
    r = R.rank_symbols({"square": square, "tee": tee, "flag": "flag"}, matcher="centroid-distance",
                       sizes=[48], angles=[0, 40], blurs=[0.0], noise_per_family=3)
    assert r.names == ["square", "tee", "flag"] and r.descriptors.shape[0] == 3
    assert r.settings["stages"]["matcher"]["name"] == "centroid-distance"
