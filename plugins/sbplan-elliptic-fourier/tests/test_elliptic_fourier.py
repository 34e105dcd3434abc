"""Tests of the elliptic-Fourier plugin: sbplan's contract suite, the maths, and the pipeline.

Run after installing the plugin (``pip install ./plugins/sbplan-elliptic-fourier``):
``python3 -m pytest plugins/sbplan-elliptic-fourier/tests``.
"""

from __future__ import annotations

import numpy as np
import pytest

from sbplan import registry as plugins
from sbplan.errors import ContourError, InputError
from sbplan.testing import MatcherContract, calibrated_pipeline, sample_outlines, tiny_floor  # noqa: F401  (fixtures)
from sbplan_elliptic_fourier import EllipticFourierMatcher, elliptic_coefficients


class TestContract(MatcherContract):
    """The class itself against sbplan's matcher contract."""

    stage_class = EllipticFourierMatcher


class TestContractThroughEntryPoint(MatcherContract):
    """What users get: the stage sbplan's registry found through the entry point."""

    stage_name = "elliptic-fourier"
    stage_options = {"harmonics": 16}


def test_found_through_the_entry_point():
    info = plugins.registry().info("matcher", "elliptic-fourier")
    assert info.cls is EllipticFourierMatcher
    assert info.origin == "sbplan-elliptic-fourier"


def test_circle_and_ellipse_coefficients():
    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    # A circle traced from (30, 0) counter-clockwise as displayed (y down): x = 30 cos, y = -30 sin.
    circle = elliptic_coefficients([np.c_[30 * np.cos(t), -30 * np.sin(t)]], harmonics=4)[0]
    assert circle[0] == pytest.approx([30, 0, 0, -30], abs=0.01)
    assert np.abs(circle[1:]).max() < 1e-6
    # An ellipse parametrized by arc length is not a pure first harmonic, but it has the ellipse's
    # symmetry: no even harmonics, no sine terms in x or cosine terms in y.
    ellipse = elliptic_coefficients([np.c_[30 * np.cos(t), -20 * np.sin(t)]], harmonics=4)[0]
    assert np.abs(ellipse[1::2]).max() < 1e-6
    assert np.abs(ellipse[:, 1:3]).max() < 1e-6
    assert ellipse[0, 0] == pytest.approx(30, rel=0.1) and ellipse[0, 3] == pytest.approx(-20, rel=0.1)


def test_normalized_first_harmonic():
    m = EllipticFourierMatcher(harmonics=5)
    d = m.describe(sample_outlines()["flag"]).reshape(5, 4)
    assert d[0, :3] == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)
    assert 0 < abs(d[0, 3]) <= 1  # the first ellipse's axis ratio


def test_mirror_image_is_a_different_shape():
    m = EllipticFourierMatcher()
    flag = sample_outlines()["flag"]
    mirrored = flag * [-1.0, 1.0]
    assert m.distance(m.describe(flag), m.describe(mirrored)) > m.default_threshold


def test_symmetric_shapes_are_stable():
    # A square's first ellipse is a circle, so Kuhl & Giardina's start point is undefined; the
    # aligned distance does not depend on it.
    m = EllipticFourierMatcher()
    sq = sample_outlines()["square"]
    for deg in (10, 30, 45, 77):
        a = np.deg2rad(deg)
        rot = sq @ np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]).T
        assert m.distance(m.describe(sq), m.describe(np.roll(rot, 1, axis=0))) < 1e-3


def test_distance_is_sqrt2_times_rms_of_aligned_outlines():
    # Two outlines that differ only in one harmonic's coefficient by eps are eps apart.
    m = EllipticFourierMatcher(harmonics=4)
    a = m.describe(sample_outlines()["blob"])
    b = a.copy()
    b[2 * 4 + 1] += 0.05  # b_3
    assert m.distance(a, b) == pytest.approx(0.05, abs=1e-3)


def test_bad_options_and_outlines():
    with pytest.raises(InputError, match="harmonics"):
        EllipticFourierMatcher(harmonics=1)
    with pytest.raises(InputError, match="harmonics"):
        EllipticFourierMatcher.from_strings(["harmonics=many"])
    m = EllipticFourierMatcher()
    with pytest.raises(ContourError):
        m.describe([[0, 0], [1, 1]])
    with pytest.raises(ContourError, match="zero-length"):
        m.describe([[2, 2], [2, 2], [2, 2]])
    with pytest.raises(InputError, match="descriptor lengths"):
        m.distance_matrix(np.zeros((1, 8)), np.zeros((1, 8)))


def test_detection_with_this_matcher(calibrated_pipeline):
    detection = calibrated_pipeline.detect(matcher="elliptic-fourier")
    assert detection.stages["matcher"] == "elliptic-fourier"
    assert calibrated_pipeline.cell_errors(detection) == 0
    assert detection.occupied.any()
