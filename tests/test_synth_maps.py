"""The committed example maps: rebuilt exactly by the generator, honest truth, usable workspaces."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest

from sbplan.cli import main
from sbplan.errors import SceneError
from sbplan.synth import OCCUPIED, GroundTruth
from sbplan.synth.maps import MAPS, build_map, recipe, route_blocked, route_clearance

ROOT = Path(__file__).resolve().parents[1] / "maps"


def _same_folder(built: Path, committed: Path) -> None:
    names = sorted(p.name for p in committed.iterdir())
    assert sorted(p.name for p in built.iterdir()) == names
    for name in names:
        a, b = built / name, committed / name
        if name.endswith(".png"):
            ia, ib = (cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in (a, b))
            assert ia.shape == ib.shape and np.array_equal(ia, ib), name
        elif name.endswith(".json"):
            assert json.loads(a.read_text()) == json.loads(b.read_text()), name
        else:
            assert a.read_text() == b.read_text(), name


# The 1920 x 1080 map takes about a second to render: it is rebuilt too (the whole file stays fast).
@pytest.mark.parametrize("name", list(MAPS))
def test_generator_rebuilds_the_committed_map_exactly(name, tmp_path):
    _same_folder(build_map(name, tmp_path / name), ROOT / name)


def test_cli_rebuilds_a_map(tmp_path, capsys):
    assert main(["synth", "--map", "paper-8x6", "-o", str(tmp_path / "p")]) == 0
    _same_folder(tmp_path / "p", ROOT / "paper-8x6")
    assert main(["synth", "--map", "nowhere", "-o", str(tmp_path / "q")]) != 0
    assert capsys.readouterr().err.startswith("sbplan: error: map: unknown map 'nowhere'")
    with pytest.raises(SceneError, match="^map:"):
        recipe("nowhere")


def test_paper_map_hides_exactly_13_symbols_in_three_separate_obstacles():
    truth = GroundTruth.from_json(ROOT / "paper-8x6" / "scene-01.json")
    assert truth.counts == {"occupied": 13, "free": 35, "ambiguous": 0}
    assert len(truth.obstacles) == 3
    # each obstacle clearly covers its cells
    assert (truth.overlap[truth.cells == OCCUPIED] > 0.9).all()
    # the occupied cells form three groups that do not touch, not even diagonally
    n, _ = cv2.connectedComponents(truth.occupied.astype(np.uint8), connectivity=8)
    assert n - 1 == 3
    # symbol centres of area at the paper's figure-6 coordinates
    assert np.allclose(truth.centres_px[0, :, 0], [47, 146, 247, 346, 445, 544, 644, 744])
    assert np.allclose(truth.centres_px[:, 0, 1], [45, 138, 229, 322, 413, 506])
    img = cv2.imread(str(ROOT / "paper-8x6" / "scene-01.png"), cv2.IMREAD_UNCHANGED)
    assert img.shape == (552, 792)


@pytest.mark.parametrize("name", list(MAPS))
def test_workspace_start_and_goal_are_clear_and_their_line_is_blocked(name):
    folder = ROOT / name
    ws = tomllib.loads((folder / "workspace.toml").read_text())
    assert set(ws) == {"grid", "origin", "robot", "route"}
    pitch, radius = ws["grid"]["pitch_m"], ws["robot"]["radius_m"]
    start, goal = ws["route"]["start_m"], ws["route"]["goal_m"]
    assert ws["origin"]["xy_m"] == [pitch[0] / 2, pitch[1] / 2]
    floor = recipe(name).floor
    for k, scene in enumerate(sorted(folder.glob("scene-*.json"))):
        truth = GroundTruth.from_json(scene)
        assert truth.counts["occupied"] > 0
        assert route_clearance(floor, truth, start, pitch) >= radius + 0.1
        assert route_clearance(floor, truth, goal, pitch) >= radius + 0.1
        if k == 0:
            assert route_blocked(floor, truth, start, goal, pitch)


def test_maps_folder_stays_small():
    total = sum(p.stat().st_size for name in MAPS for p in (ROOT / name).iterdir())
    assert total < 6_000_000
