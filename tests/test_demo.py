"""The README's main job: `sbplan demo` on maps/paper-8x6 reproduces the paper's worked example."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import shapely

ROOT = Path(__file__).resolve().parents[1]


def test_demo_on_the_paper_floor(tmp_path):
    out = subprocess.run([sys.executable, "-m", "sbplan", "demo", str(ROOT / "maps" / "paper-8x6"), "-o", str(tmp_path)],
                         capture_output=True, text=True, check=True).stdout
    assert "symbols: 48 expected, 35 found" in out
    assert "occupied cells: 13" in out and "obstacles: 3" in out
    result = json.loads((tmp_path / "result.json").read_text())
    truth = json.loads((ROOT / "maps" / "paper-8x6" / "scene-01.json").read_text())
    occupied_truth = sorted([r, c] for r, row in enumerate(truth["cells"]) for c, v in enumerate(row) if v == 1)
    assert result["occupied_cells"] == occupied_truth
    assert (result["symbols_expected"], result["symbols_found"], len(result["obstacles"])) == (48, 35, 3)
    route = json.loads((tmp_path / "route.json").read_text())
    assert route["status"] == "exact"
    path = shapely.LineString(route["waypoints"])
    for ob in result["obstacles"]:
        # the route keeps the robot's radius from every detected obstacle as the planner had it (the
        # default obstacle model's parts, which hold the footprint), with a hair of slack
        for part in ob["parts_m"]:
            assert path.distance(shapely.Polygon(part)) >= result["workspace"]["robot_radius_m"] - 1e-6
        assert shapely.union_all([shapely.Polygon(p) for p in ob["parts_m"]]).buffer(1e-6).contains(
            shapely.Polygon(ob["outline_m"]))
    for name in ("calibration.json", "overlay.png", "occupancy.png", "obstacles.geojson", "nav2/map.yaml", "nav2/map.pgm"):
        assert (tmp_path / name).is_file(), name
