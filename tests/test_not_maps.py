"""Pictures in the camera's pixels are not maps (issue 18, item 3): the occupancy image and the
overlay say what they are in their metadata, and ``sbplan plan`` refuses them, naming the files
to plan on; a nav2 map's image is refused without its map.yaml."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from _outputs_fixtures import ROOT, paper
from sbplan.detection import exports
from sbplan.errors import MapFormatError
from sbplan.imageio import image_text, load_image, write_image
from sbplan.planning import load_obstacles


@pytest.mark.parametrize("name", ["occupancy.png", "occupancy.pgm"])
def test_the_occupancy_image_is_refused_as_a_map(tmp_path, name):
    _, det, _ = paper()
    path = exports.write_occupancy(tmp_path / name, det)
    assert image_text(path)["sbplan"] == "camera-occupancy"
    np.testing.assert_array_equal(load_image(path), det.occupancy)  # the metadata leaves the pixels alone
    with pytest.raises(MapFormatError, match="camera's pixels.*result.json.*map.yaml"):
        load_obstacles(path)


def test_the_overlay_is_refused_as_a_map(tmp_path):
    _, det, image = paper()
    path = exports.write_overlay(tmp_path / "overlay.png", image, det)
    with pytest.raises(MapFormatError, match="overlay"):
        load_obstacles(path)


def test_a_nav2_image_is_refused_without_its_yaml(tmp_path):
    _, det, _ = paper()
    exports.write_nav2(tmp_path, det)
    with pytest.raises(MapFormatError, match="map.yaml"):
        load_obstacles(tmp_path / "map.pgm")
    assert load_obstacles(tmp_path / "map.yaml").polygons  # the map itself loads


def test_plan_on_the_demo_occupancy_image_is_one_error_line(tmp_path):
    """The demo's pictures (written as one folder, not through write_occupancy) say what they are too."""
    from sbplan.commands.demo import demo_files

    cal, det, image = paper()
    files = demo_files(cal, image, det)
    for name in ("occupancy.png", "overlay.png"):
        (tmp_path / name).write_bytes(files[name])
        with pytest.raises(MapFormatError, match="result.json"):
            load_obstacles(tmp_path / name)
    r = subprocess.run([sys.executable, "-m", "sbplan", "plan", "--obstacles", str(tmp_path / "occupancy.png"),
                        "--start", "0.1,1.4", "--goal", "3.9,1.6", "--radius", "0.15"], capture_output=True, text=True)
    assert r.returncode != 0 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sbplan: error:") and "result.json" in lines[0]


def test_a_plain_occupancy_image_without_metadata_is_still_a_map(tmp_path):
    img = np.full((20, 30), 255, np.uint8)
    img[5:10, 5:15] = 0
    write_image(tmp_path / "plain.png", img)
    assert image_text(tmp_path / "plain.png") == {}
    got = load_obstacles(tmp_path / "plain.png")
    assert got.bounds == (0.0, 0.0, 30.0, 20.0) and sum(p.area for p in got.polygons) == 50.0
    # and the OMPL mazes (written by other programs) load as before
    assert load_obstacles(ROOT / "maps" / "ompl-mazes" / "ompl-maze-thin.png").polygons


def test_image_text_survives_garbage(tmp_path):
    for data in (b"", b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfftEXt", b"P5\n# a: b", b"P"):
        (tmp_path / "x").write_bytes(data)
        assert isinstance(image_text(tmp_path / "x"), dict)
    assert image_text(tmp_path / "missing.png") == {}
