"""The planner API as a user's script meets it (issue 18, item 10): a fresh plan is not a
replanned one, the route's time has one name in Python and in JSON, OMPL's planners answer to
OMPL's own names, and the command line uses only the public API."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest
from shapely.geometry import LineString, box

import sbplan
from sbplan import registry
from sbplan.errors import UnknownStageError

ROOT = Path(__file__).resolve().parents[1]
WALL = [box(4, 2, 6, 8)]


def test_a_fresh_plan_is_not_replanned_and_a_replan_is():
    route = sbplan.plan(WALL, (1, 5), (9, 5), robot_radius=0.2, bounds=(0, 0, 10, 10))
    straight = sbplan.plan(WALL, (1, 1), (9, 1), robot_radius=0.2, bounds=(0, 0, 10, 10))
    assert not route.replanned and not straight.replanned
    untouched = sbplan.replan(route, route.waypoints[0], [box(0.2, 9.0, 0.4, 9.2)])
    assert not untouched.replanned
    block = box(7.0, 2.5, 7.5, 3.5)  # on the route's last leg
    assert LineString(route.waypoints).intersects(block)
    detour = sbplan.replan(route, route.waypoints[0], [block])
    assert detour.replanned and LineString(detour.waypoints).distance(block) >= 0.2 - 1e-6


def test_the_route_time_has_one_name():
    route = sbplan.plan(WALL, (1, 5), (9, 5), robot_radius=0.2, bounds=(0, 0, 10, 10))
    assert route.time_s > 0 and not hasattr(route, "time")
    data = route.to_dict()
    assert set(data) == {"format", "status", "planner", "length", "time_s", "replanned", "waypoints"}
    assert data["time_s"] == route.time_s and data["format"] == "sbplan.route/1"


@pytest.mark.parametrize("ompl_name, stage", [("RRTConnect", "rrt-connect"), ("RRTstar", "rrt-star"),
                                              ("InformedRRTstar", "informed-rrt-star"), ("PRMstar", "prm-star"),
                                              ("BITstar", "bit-star"), ("FMT", "fmt-star")])
def test_ompl_planners_answer_to_their_ompl_names(ompl_name, stage):
    assert registry.planner(ompl_name).name == stage
    assert ompl_name not in registry.planner_names() and stage in registry.planner_names()


def test_plan_with_an_ompl_name():
    route = sbplan.plan(WALL, (1, 5), (9, 5), robot_radius=0.2, bounds=(0, 0, 10, 10), planner="RRTConnect",
                        time_limit=0.5)
    assert route.planner == "rrt-connect" and route.status == "exact"
    with pytest.raises(UnknownStageError, match="rrtconnect"):
        sbplan.plan(WALL, (1, 5), (9, 5), robot_radius=0.2, bounds=(0, 0, 10, 10), planner="rrtconnect")


def test_the_cli_plans_by_an_ompl_name():
    r = subprocess.run([sys.executable, "-m", "sbplan", "plan", "--obstacles",
                        str(ROOT / "maps" / "ompl-mazes" / "ompl-maze-normal.png"), "--start", "205,445", "--goal",
                        "205,400", "--radius", "2", "--planner", "RRTConnect", "--time-limit", "0.5", "--json"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["planner"] == "rrt-connect"


def _private_uses(path: Path):
    """Underscored names the command takes from other sbplan modules: imported, passed as keywords
    or read as attributes (its own helpers and argparse's namespace excepted)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.module == "__future__":
                continue
            inside_commands = node.level == 1
            parts = (node.module or "").split(".")
            if not inside_commands and any(p.startswith("_") for p in parts):
                yield node.lineno, node.module
            for alias in node.names:
                if alias.name.startswith("_") and not inside_commands:
                    yield node.lineno, alias.name
        elif isinstance(node, ast.Call):
            callee = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
            for kw in node.keywords:
                if kw.arg and kw.arg.startswith("_") and callee != "set_defaults":
                    yield node.lineno, kw.arg
        elif isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            if not (isinstance(node.value, ast.Name) and node.value.id == "args"):
                yield node.lineno, node.attr


def test_the_commands_use_the_public_api_only():
    found = [(p.name, line, name) for p in sorted((ROOT / "sbplan" / "commands").glob("*.py"))
             for line, name in _private_uses(p)]
    assert not found, found
