"""The built-in candidate symbol library (plugins/sbplan_symbols)."""

from __future__ import annotations

import numpy as np
import pytest
from shapely import affinity
from shapely.geometry import Polygon

from sbplan import registry as plugins
from sbplan.errors import SceneError
from sbplan.synth import DEFAULT_SYMBOL, rings_centroid, symbol_outline


@pytest.fixture(scope="module")
def symbols():
    return plugins.registry().symbols()


def test_at_least_thirty_symbols_with_unique_names_and_descriptions(symbols):
    assert len(symbols) >= 30
    names = list(symbols)
    assert len(set(names)) == len(names)
    assert all(symbols[n].description.strip() for n in names)
    for family in ("flag", "cross", "letter-l", "letter-t", "letter-e", "letter-f", "arrow", "star-5",
                   "notched-square", "circle", "ellipse", "ring", "rounded-square"):
        assert family in symbols


def test_every_symbol_is_a_valid_simple_polygon_in_the_unit_box(symbols):
    for name in symbols:
        rings = symbol_outline(name)
        poly = Polygon(rings[0], rings[1:])
        assert poly.is_valid and poly.area > 0.05, name
        pts = np.vstack(rings)
        assert pts.min() >= -1e-9 and pts.max() <= 1 + 1e-9, name
        assert np.isclose(np.ptp(pts, axis=0).max(), 1.0), name
        # outline counter-clockwise as displayed (negative shoelace with y down), holes clockwise
        x, y = rings[0][:, 0], rings[0][:, 1]
        assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0, name
        for hole in rings[1:]:
            x, y = hole[:, 0], hole[:, 1]
            assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0, name


def _self_overlap(poly: Polygon, moved: Polygon) -> float:
    return poly.symmetric_difference(moved).area / poly.area


def test_default_symbol_is_asymmetric_without_holes():
    rings = symbol_outline(DEFAULT_SYMBOL)
    assert len(rings) == 1
    poly = Polygon(rings[0])
    c, _ = rings_centroid(rings)
    for angle in (90, 180, 270):
        assert _self_overlap(poly, affinity.rotate(poly, angle, origin=tuple(c))) > 0.2
    for xf, yf in ((-1, 1), (1, -1)):
        assert _self_overlap(poly, affinity.scale(poly, xf, yf, origin=tuple(c))) > 0.2
    # and the symmetric shapes really are symmetric, so the check can tell
    cross = Polygon(symbol_outline("cross")[0])
    cc, _ = rings_centroid(symbol_outline("cross"))
    assert _self_overlap(cross, affinity.rotate(cross, 90, origin=tuple(cc))) < 1e-6


def test_symbol_outline_takes_raw_polygons_and_rejects_bad_ones():
    square = symbol_outline([(0, 0), (1, 0), (1, 1), (0, 1)])
    assert len(square) == 1 and square[0].shape == (4, 2)
    with pytest.raises(SceneError, match="^symbol:"):
        symbol_outline([(0, 0), (1, 1), (1, 0), (0, 1)])  # bow tie
    with pytest.raises(SceneError, match="^symbol:"):
        symbol_outline("no-such-symbol")
