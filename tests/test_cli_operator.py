"""What an operator trips over on the command line (issue 17, items 7, 9, 10 and 12): bare command
groups, grid sizes said columns first, progress of the benchmarks on stderr, and what each
planner guarantees. Real commands, run through the CLI's entry point in this process; what
reaches the terminal is read from the file descriptors."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "maps" / "paper-8x6"


@pytest.fixture
def sbplan(capfd):
    """``sbplan ARGS...`` run in this process (``sbplan.cli.main``), its output read from the
    file descriptors, so that what OpenCV, OMPL or a server write there is seen too."""
    from sbplan.cli import main

    def run(*args):
        capfd.readouterr()
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:  # argparse's own exits: help, usage errors
            code = exc.code
        out, err = capfd.readouterr()
        return subprocess.CompletedProcess(args, code, out, err)

    return run


@pytest.mark.parametrize("group, listed", [("synth", "--map NAME"), ("bench", "stages"), ("symbols", "rank")])
def test_a_bare_command_group_prints_its_help(sbplan, group, listed):
    r = sbplan(group)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"usage: sbplan {group}") and listed in r.stdout
    assert r.stderr == ""


def test_grid_sizes_are_said_columns_first(sbplan, tmp_path):
    r = sbplan("calibrate", PAPER / "reference.png", "-o", tmp_path / "cal.json")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("grid 8 columns × 6 rows (48 symbols)"), r.stdout
    r = sbplan("synth", "-o", tmp_path / "floor", "--size", "640x480", "--grid", "6x4", "--scenes", "0")
    assert r.returncode == 0, r.stderr
    assert "(6 columns × 4 rows of symbols, 640 x 480 px" in r.stdout
    r = sbplan("synth", "--list")
    assert "8 columns × 6 rows of symbols" in r.stdout and " x 6 symbols" not in r.stdout


BENCHES = [
    ("stages", ("--repeat", "1")),
    ("match", ("--classes", "3", "--per-class", "3", "--repeat", "1")),
    ("detect", ("--conditions", "clean", "--scenes", "1", "--size", "640x480", "--grid", "6x4", "--repeat", "1",
                "--variants", "default", "--slow-scenes", "0")),
    ("plan", ("--quick", "--worlds", "rect-5", "--ompl-queries", "0")),
    ("watch", ("--sizes", "320x240", "--frames", "24", "--loops", "1", "--streams", "0", "--fps", "240")),
    ("serve", ("--clients", "1", "--seconds", "0.1", "--warmup", "0", "--repeats", "1", "--queries", "2",
               "--paced", "")),
]


@pytest.mark.parametrize("name, args", BENCHES, ids=[b[0] for b in BENCHES])
def test_every_benchmark_shows_progress_on_stderr_and_only_json_on_stdout(sbplan, name, args, tmp_path):
    if name == "match":
        args = ("--make", tmp_path / "silhouettes", *args)
    if name == "serve":
        pytest.importorskip("fastapi")
        pytest.importorskip("uvicorn")
    r = sbplan("bench", name, *args, "--json")
    assert r.returncode == 0, r.stderr
    json.loads(r.stdout)  # nothing a --json consumer would have to strip
    # (the watch stream bumps the camera on purpose: no "camera moved" warning per stream)
    assert "camera moved" not in r.stderr, r.stderr
    if name == "match":  # its own progress lines: one per matcher and step, with the time taken
        assert all(m in r.stderr for m in ("centroid-distance", "fourier", "hu-moments")), r.stderr
        return
    if name == "serve":  # its own lines: the set-up, then one per load level
        assert "starting sbplan serve" in r.stderr and "1 clients, run 1" in r.stderr, r.stderr
        return
    steps = [line for line in r.stderr.splitlines() if line.startswith(f"bench {name}: [")]
    assert steps, r.stderr
    # "[k/n] what": numbered steps, the last one n of n
    last = steps[-1].split("[", 1)[1].split("]", 1)[0]
    done, total = map(int, last.split("/"))
    assert done == total >= 1


def test_each_planner_says_what_it_guarantees_and_only_aux_corner_is_exact(sbplan, tmp_path):
    maze = ROOT / "maps" / "ompl-mazes" / "ompl-maze-normal.png"
    common = ("plan", "--obstacles", maze, "--start", "205,445", "--goal", "205,400", "--radius", "2")
    exact = sbplan(*common)
    assert exact.returncode == 0, exact.stderr
    assert exact.stdout.startswith("exact route by aux-corner (proven shortest for the robot's radius): length")
    for planner, guarantee in (("rrt-connect", "collision-free, not shortest"),
                               ("rrt-star", "collision-free, near-shortest, not proven")):
        r = sbplan(*common, "--planner", planner, "--time-limit", "0.1")
        assert r.returncode == 0, r.stderr
        assert r.stdout.startswith(f"route by {planner} ({guarantee}): length"), r.stdout
        data = json.loads(sbplan(*common, "--planner", planner, "--time-limit", "0.1", "--json").stdout)
        assert data["exact"] is False and data["guarantee"] == guarantee
    data = json.loads(sbplan(*common, "--json").stdout)
    assert data["exact"] is True and data["status"] == "exact"
