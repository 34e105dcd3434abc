"""The library logs and never prints; the command line shows the log (issue 18, item 7).

Every module logs to a child of the ``sbplan`` logger; ``sbplan`` shows warnings and errors on
stderr, ``-v``/``-vv`` more, ``-q`` errors only, ``--log-json`` one JSON object a line."""

from __future__ import annotations

import ast
import json
import logging
import subprocess
import sys
from pathlib import Path

import pytest

from _outputs_fixtures import ROOT, moved_floor, paper

#: Where printing is the job: the command line, its commands, and the ``sbplan bench`` commands'
#: tables and progress lines (sbplan/bench/ is their implementation; evaluation.py, which the
#: tests and plugins use as a library, is not).
PRINTING_ALLOWED = {"sbplan/cli.py", "sbplan/commands", "sbplan/bench"}
PRINTING_FORBIDDEN = {"sbplan/bench/evaluation.py"}


def _prints(path: Path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "print":
            fn = node
            while fn in parents and not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                fn = parents[fn]
            yield node.lineno, getattr(fn, "name", "<module>")


def test_the_library_never_prints():
    found = []
    for folder in [ROOT / "sbplan", *sorted((ROOT / "plugins").glob("sbplan_*"))]:
        for path in folder.rglob("*.py"):
            rel = path.relative_to(ROOT).as_posix()
            if rel not in PRINTING_FORBIDDEN and any(rel == a or rel.startswith(a + "/") for a in PRINTING_ALLOWED):
                continue
            found += [f"{rel}:{line} in {fn}" for line, fn in _prints(path)]
    assert not found, found


@pytest.fixture(scope="module")
def moved():
    return moved_floor()


def test_calibrate_detect_and_plan_log_and_print_nothing(capsys, caplog):
    import sbplan
    from sbplan.detection import Detector

    caplog.set_level(logging.DEBUG, logger="sbplan")
    paper.cache_clear()
    cal, det, image = paper()
    Detector(cal)(image)
    ws = cal.workspace
    sbplan.plan([ob.mar_m for ob in det.obstacles], ws.start_m, ws.goal_m, robot_radius=ws.robot_radius_m,
                bounds=cal.world_bounds())
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""
    records = [r for r in caplog.records if r.name.startswith("sbplan.")]
    messages = [r.getMessage() for r in records]
    assert any(r.levelno == logging.INFO and r.getMessage().startswith("calibrated: grid 8 x 6") for r in records)
    assert any(r.levelno == logging.DEBUG and "binarizer background" in m for r, m in zip(records, messages))
    timings = [r for r in records if getattr(r, "data", {}).get("timings_ms")]
    assert timings and timings[-1].data["timings_ms"]["total"] > 0 and timings[-1].data["obstacles"] == 3
    assert any(m == "planner aux-corner" for m in messages)


def test_a_moved_camera_is_a_logged_warning(moved, caplog):
    from sbplan.detection import Detector

    cal, image = moved
    caplog.set_level(logging.WARNING, logger="sbplan")
    det = Detector(cal)(image)
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING and r.name == "sbplan.detection.detector"]
    assert len(warnings) == 1 and warnings[0].getMessage() == det.camera.warning
    assert "calibrate --update" in det.camera.warning and warnings[0].data["camera"]["model"] == "similarity"


def test_the_command_line_shows_the_log(moved, tmp_path):
    cal, image = moved
    import cv2

    cal.save(tmp_path / "cal.json")
    cv2.imwrite(str(tmp_path / "moved.png"), image)

    def detect(*options):
        r = subprocess.run([sys.executable, "-m", "sbplan", *options, "detect", str(tmp_path / "moved.png"), "-c",
                            str(tmp_path / "cal.json")], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        return r

    default = detect().stderr.splitlines()
    assert len(default) == 1 and default[0].startswith("sbplan: warning: ") and "calibrate --update" in default[0]
    assert detect("-q").stderr == ""
    lines = [json.loads(line) for line in detect("--log-json").stderr.splitlines()]
    assert [(r["level"], r["logger"]) for r in lines] == [("warning", "sbplan.detection.detector")]
    assert lines[0]["data"]["camera"]["symbols_used"] >= 10 and lines[0]["time"].endswith("+00:00")
    debug = detect("-vv").stderr
    assert "sbplan: debug: [sbplan.detection.detector]" in debug and "ms (" in debug
    err = subprocess.run([sys.executable, "-m", "sbplan", "--log-json", "detect", str(tmp_path / "missing.png"), "-c",
                          str(tmp_path / "cal.json")], capture_output=True, text=True)
    record = json.loads(err.stderr)
    assert err.returncode != 0 and record["level"] == "error" and "missing.png" in record["message"]


def test_configure_undoes_itself():
    from sbplan.logs import configure

    logger = logging.getLogger("sbplan")
    before = (list(logger.handlers), logger.level, logger.propagate)
    undo = configure(verbosity=2)
    assert logger.level == logging.DEBUG and not logger.propagate
    undo()
    assert (list(logger.handlers), logger.level, logger.propagate) == before


def test_importing_sbplan_configures_no_output():
    code = ("import logging, sbplan; from sbplan.detection import detector; "
            "detector.log.warning('x'); print(logging.getLogger('sbplan').handlers)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0 and r.stderr == "" and "NullHandler" in r.stdout


def test_a_plugin_that_failed_to_load_shows_with_v_only(tmp_path):
    """The registry's warning about a broken plugin is for those who ask: -v shows it, a command
    that does not need the plugin says nothing (the hardening's rule), other warnings still show."""
    dist = tmp_path / "broken_sbplan_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-sbplan-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[sbplan]\nbroken = sbplan_module_that_does_not_exist\n")
    import os

    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    run = lambda *a: subprocess.run([sys.executable, "-m", "sbplan", *a, "symbols", "list"],  # noqa: E731
                                    capture_output=True, text=True, env=env)
    assert run().stderr == ""
    assert "plugin 'broken'" in run("-v").stderr
