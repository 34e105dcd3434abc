"""Outputs never destroy what they must not (issue 21, items 1-3; issue 18, item 5).

Special files are never replaced (a FIFO, a symbolic link and a device stand-in made in the test's
own folder: nothing is written outside it), an output is never one of the command's inputs, the
files that belong together (a nav2 map, the demo's folder, rendered scenes) are written as one unit that survives
kill -9 and concurrent writers, and every output error is one line.
"""

from __future__ import annotations

import os
import pickle
import random
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

from sbplan.cli import main
from sbplan.detection import Detector, exports
from sbplan.errors import OutputError
from sbplan.files import check_outputs, clean_stale_temporaries, write_atomic, write_file_set
from sbplan.imageio import write_image, write_json
from sbplan.planning import load_obstacles
from sbplan.synth import SceneSpec, render_scene

from _small_floor import FLOOR, calibrated_floor

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def floor(tmp_path_factory):
    """A calibrated floor on disk and two detections with different obstacles."""
    folder = tmp_path_factory.mktemp("floor")
    cal = calibrated_floor(folder)
    scenes = []
    for seed in (3, 4):
        image, _ = render_scene(FLOOR, SceneSpec(n_obstacles=2), seed=seed)
        write_image(folder / f"scene-{seed}.png", image)
        scenes.append((image, Detector(cal)(image)))
    return folder, cal, scenes


def _cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


# -- item 1: special files are never replaced ---------------------------------------------------
@pytest.mark.parametrize("kind", ["fifo", "symlink", "folder"])
def test_outputs_refuse_special_files_and_leave_them_as_they_were(floor, tmp_path, capsys, kind):
    folder, cal, _ = floor
    target = tmp_path / "out.json"
    keep = tmp_path / "keep.json"
    keep.write_text("precious")
    if kind == "fifo":
        os.mkfifo(target)
    elif kind == "symlink":
        target.symlink_to(keep)
    else:
        target.mkdir()
    code, out, err = _cli(capsys, "calibrate", folder / "reference.png", "-o", target)
    assert code == 4 and out == "" and err.count("\n") == 1 and err.startswith("sbplan: error:")
    assert str(target) in err
    if kind == "fifo":
        assert target.is_fifo()
    elif kind == "symlink":
        assert target.is_symlink() and keep.read_text() == "precious"
    else:
        assert target.is_dir()
    # the library refuses too, not only the command
    with pytest.raises(OutputError):
        cal.save(target)
    assert keep.read_text() == "precious"


def test_a_device_is_not_replaced(tmp_path):
    # /dev/null itself is never touched: a character device is found by lstat, which is what
    # _check_target reads; the stand-in is a socket made in the test's folder (no root needed)
    import socket

    sock_path = tmp_path / "s.json"
    with socket.socket(socket.AF_UNIX) as s:
        s.bind(str(sock_path))
        with pytest.raises(OutputError, match="not a regular file"):
            write_json(sock_path, {"a": 1})
        assert sock_path.is_socket()


# -- item 2: an output is never one of the inputs ------------------------------------------------
def test_outputs_that_are_inputs_are_refused_before_any_work(floor, tmp_path, capsys):
    folder, _, _ = floor
    cal = tmp_path / "cal.json"
    cal.write_bytes((folder / "cal.json").read_bytes())
    scene = tmp_path / "scene.png"
    scene.write_bytes((folder / "scene-3.png").read_bytes())
    before = {p: p.read_bytes() for p in (cal, scene)}
    for argv in (["detect", scene, "-c", cal, "-o", cal],
                 ["detect", scene, "-c", cal, "--overlay", scene],
                 ["detect", scene, "-c", cal, "--occupancy", tmp_path / "." / "scene.png"],
                 ["detect", scene, "-c", cal, "--nav2", tmp_path],
                 ["calibrate", scene, "-o", scene],
                 ["calibrate", "--update", cal, scene, "-o", scene],
                 ["plan", "--obstacles", cal, "--start", "0,0", "--goal", "1,1", "--radius", "0", "--plot", cal]):
        code, out, err = _cli(capsys, *argv)
        assert code == 4 and "input" in err and err.count("\n") == 1, (argv, err)
    assert {p: p.read_bytes() for p in (cal, scene)} == before
    # a hard link is the same file under another name
    os.link(cal, tmp_path / "same.json")
    code, _, err = _cli(capsys, "detect", scene, "-c", cal, "-o", tmp_path / "same.json")
    assert code == 4 and "input -c" in err
    # one file for two outputs
    code, _, err = _cli(capsys, "detect", scene, "-c", cal, "-o", tmp_path / "r.json", "--geojson", tmp_path / "r.json")
    assert code == 4 and "also the output of -o" in err
    # updating a calibration in place is what --update is for
    code, out, err = _cli(capsys, "calibrate", "--update", cal, folder / "scene-3.png")
    assert code == 0, err


# -- item 3: files that belong together are one unit ---------------------------------------------
def test_nav2_and_demo_folders_are_written_whole_and_refuse_foreign_files(floor, tmp_path, monkeypatch):
    folder, cal, scenes = floor
    image, detection = scenes[0]
    nav = tmp_path / "nav2"
    exports.write_nav2(nav, detection)
    assert sorted(p.name for p in nav.iterdir()) == ["map.pgm", "map.yaml"]
    exports.write_nav2(nav, detection, resolution=0.01)  # replaced as a whole
    assert load_obstacles(nav / "map.yaml").bounds == pytest.approx(cal.world_bounds(), abs=0.011)
    (nav / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="notes.txt"):
        exports.write_nav2(nav, detection)
    assert (nav / "notes.txt").read_text() == "mine"
    monkeypatch.chdir(tmp_path)
    with pytest.raises(OutputError, match="working folder"):
        exports.write_nav2(".", detection)
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


def _variants(floor) -> list[dict]:
    """The demo's output folder for the two scenes: every file says which scene it is from."""
    from sbplan.commands.demo import demo_files

    _, cal, scenes = floor
    return [demo_files(cal, image, detection) for image, detection in scenes]


def _consistent(folder: Path, variants: list[dict]) -> int | None:
    """Which variant the folder holds (every file from the same one), None if absent; fails on a mix."""
    if not folder.exists():
        return None
    dir_fd = os.open(folder, os.O_RDONLY)  # one folder for every file read, as a careful reader does
    try:
        seen = set()
        for name in ("result.json", "obstacles.geojson", "nav2/map.yaml", "nav2/map.pgm", "overlay.png"):
            try:
                with open(name, "rb", opener=lambda p, f: os.open(p, f, dir_fd=dir_fd)) as fh:
                    data = fh.read()
            except FileNotFoundError:  # the folder was swapped out and removed while we read it
                return None
            matches = {k for k, v in enumerate(variants)
                       if (v[name].encode() if isinstance(v[name], str) else v[name]) == data}
            assert matches, f"{name} is from no complete run"
            seen.add(frozenset(matches))
        common = frozenset.intersection(*seen)
        assert common, f"files from different runs: {seen}"
        return min(common)
    finally:
        os.close(dir_fd)


# A writer process that forks the writers the tests kill: forking costs a millisecond where a new
# Python costs half a second, and a forked writer is killed by SIGKILL like any process.
WRITERS = textwrap.dedent("""
    import os, pickle, sys
    from sbplan.files import write_file_set, write_folder
    variants, folder, names = pickle.load(open(sys.argv[1], "rb"))

    def filler(files):  # write_folder's way (synth's scenes, maps, sequences): files written into a folder
        def fill(tmp):
            for rel, content in files.items():
                path = os.path.join(tmp, *rel.split("/"))
                os.makedirs(os.path.dirname(path), exist_ok=True)
                with open(path, "wb") as fh:
                    fh.write(content.encode() if isinstance(content, str) else content)
        return fill

    def writer(start, count):
        i = start
        while count is None or i - start < count:
            files = variants[i % len(variants)]
            if (i // 2) % 2:
                write_folder(folder, filler(files), names=names)
            else:
                write_file_set(folder, files, names=names)
            if i == start:  # one write(2) per line: writers share the pipe
                os.write(1, f"ready {os.getpid()}\\n".encode())
            i += 1

    def fork(start, count):
        pid = os.fork()
        if pid == 0:
            code = 1
            try:
                writer(start, count)
                code = 0
            finally:
                os._exit(code)
        return pid

    for line in sys.stdin:
        cmd, *args = line.split()
        if cmd == "one":  # a writer writing until the test kills it
            pid = fork(int(args[0]), None)
            os.waitpid(pid, 0)
            os.write(1, b"reaped\\n")
        elif cmd == "many":  # n writers at once, each writing `count` sets
            pids = [fork(k, int(args[1])) for k in range(int(args[0]))]
            codes = [os.waitstatus_to_exitcode(os.waitpid(p, 0)[1]) for p in pids]
            os.write(1, ("done " + " ".join(map(str, codes)) + "\\n").encode())
""")


@pytest.fixture
def writers(floor, tmp_path):
    from sbplan.commands.demo import DEMO_FILES

    variants = _variants(floor)
    job = tmp_path / "job.pickle"
    job.write_bytes(pickle.dumps((variants, str(tmp_path / "out"), DEMO_FILES)))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "plugins"),
                                                        os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-c", WRITERS, str(job)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env, cwd=tmp_path, text=True, bufsize=1)
    # bounded in time: a writer that hangs is killed, its pipe closes and the test fails on it
    watchdog = threading.Timer(120, proc.kill)
    watchdog.start()
    try:
        yield proc, variants, tmp_path / "out"
    finally:
        watchdog.cancel()
        proc.stdin.close()
        proc.wait(timeout=30)


def test_kill_9_during_writes_leaves_only_complete_sets(floor, writers, tmp_path):
    proc, variants, out = writers
    rng = random.Random(0)
    held = set()
    interrupted = 0
    t0 = time.monotonic()
    for run in range(30):
        proc.stdin.write(f"one {run}\n")
        ready = proc.stdout.readline().split()
        assert ready[:1] == ["ready"], proc.stderr.read()
        time.sleep(rng.uniform(0.0, 0.03))  # the writes go on: killed anywhere in one
        os.kill(int(ready[1]), signal.SIGKILL)
        assert proc.stdout.readline() == "reaped\n"
        # killed mid-write: its temporary is there until the next writer removes it
        interrupted += any(p.name.startswith(".out.") for p in tmp_path.iterdir())
        held.add(_consistent(out, variants))
        # what nav2 and `sbplan plan` read agrees with itself (not a 62x wrong scale)
        bounds = load_obstacles(out / "nav2" / "map.yaml").bounds
        assert bounds == pytest.approx(floor[1].world_bounds(), abs=0.06)
    assert held <= {0, 1} and time.monotonic() - t0 < 60
    assert interrupted >= 10, f"only {interrupted} of 30 kills interrupted a write: the test tested little"
    # the killed runs' temporaries go with the next write
    from sbplan.commands.demo import DEMO_FILES

    write_file_set(out, variants[0], names=DEMO_FILES)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".out.")] == []
    assert _consistent(out, variants) == 0


def test_four_concurrent_writers_leave_one_complete_set(writers, tmp_path):
    proc, variants, out = writers
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, "")), daemon=True)
    proc.stdin.write("many 4 15\n")
    reader.start()
    reads = 0
    deadline = time.monotonic() + 60
    while not any(line.startswith("done") for line in lines) and time.monotonic() < deadline:
        if _consistent(out, variants) is not None:  # a reader during the writes: never a mix
            reads += 1
    done = next(line for line in lines if line.startswith("done"))
    assert done.split() == ["done", "0", "0", "0", "0"], proc.stderr.read()
    assert sum(line.startswith("ready") for line in lines) == 4, lines
    assert _consistent(out, variants) in (0, 1) and reads > 0
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []



def test_synth_folders_are_replaced_whole_and_survive_kill_9(tmp_path, capsys):
    out = tmp_path / "scenes"
    args = ["synth", "-o", out, "--size", "320x240", "--grid", "6x4", "--obstacles", "1"]
    names = lambda: sorted(p.name for p in out.iterdir())  # noqa: E731
    assert main([str(a) for a in [*args, "--scenes", "2", "--seed", "1"]]) == 0
    first = (out / "reference.png").read_bytes()
    # another seed and fewer scenes: no scene of the first run stays beside the new reference
    assert main([str(a) for a in [*args, "--scenes", "1", "--seed", "2"]]) == 0
    assert names() == ["reference.png", "scene-01.json", "scene-01.png"]
    assert (out / "reference.png").read_bytes() != first
    kept = {p.name: p.read_bytes() for p in out.iterdir()}
    # killed after its first scene (the lines are printed as the scenes are written): the last
    # complete folder stays, the killed run's temporary goes with the next write
    env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=os.pathsep.join(
        [str(ROOT), str(ROOT / "plugins"), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-m", "sbplan", *map(str, args), "--scenes", "40", "--seed", "3"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, cwd=tmp_path, text=True)
    watchdog = threading.Timer(120, proc.kill)
    watchdog.start()
    try:
        line = proc.stdout.readline()
        proc.kill()
        proc.wait(timeout=30)
    finally:
        watchdog.cancel()
    assert line.startswith("scene-01:"), (line, proc.stderr.read())
    assert {p.name: p.read_bytes() for p in out.iterdir()} == kept
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".scenes.")], "the kill hit no write"
    # a file sbplan did not write there is refused, not deleted
    (out / "notes.txt").write_text("mine")
    code = main([str(a) for a in [*args, "--scenes", "1"]])
    assert code == 4 and "notes.txt" in capsys.readouterr().err
    (out / "notes.txt").unlink()
    assert main([str(a) for a in [*args, "--scenes", "1", "--seed", "2"]]) == 0
    assert {p.name: p.read_bytes() for p in out.iterdir()} == kept  # same seed, same files
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []

def test_stale_temporaries_of_dead_processes_are_removed_live_ones_kept(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(dead.stdout)
    from sbplan.files import _HOST

    stale = tmp_path / f".result.json.{_HOST}-{pid}-abc123.tmp"
    stale.write_bytes(b"x" * 1000)
    mine = tmp_path / f".result.json.{_HOST}-{os.getpid()}-abc123.tmp"
    mine.write_bytes(b"y")
    old_style = tmp_path / ".result.json.k3j4h5g6.tmp"
    old_style.write_bytes(b"z")
    write_atomic(tmp_path / "result.json", "{}")
    assert not stale.exists() and mine.exists() and old_style.exists()
    os.utime(old_style, (time.time() - 7200, time.time() - 7200))
    assert clean_stale_temporaries(tmp_path) == [old_style.name]


# -- issue 18, item 5: every output error is one line ---------------------------------------------
def test_output_errors_are_one_line(floor, tmp_path, capsys):
    folder, _, _ = floor
    scene, cal = folder / "scene-3.png", folder / "cal.json"
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "file.txt").write_text("x")
    cases = [(["--nav2", tmp_path / "fifo"], "not a folder"),
             (["--nav2", tmp_path / "file.txt"], "is a file"),
             (["-o", tmp_path / "file.txt" / "x.json"], "is a file"),
             (["--occupancy", tmp_path / "x.jpgx"], "'.jpgx'"),
             (["--overlay", tmp_path / "x"], "no ending"),
             (["-o", tmp_path], "is a folder")]
    for extra, what in cases:
        code, out, err = _cli(capsys, "detect", scene, "-c", cal, *extra)
        assert code == 4 and what in err and err.count("\n") == 1 and "Traceback" not in err, (extra, err)
    # a folder that cannot be made, a file system that refuses: OS errors are one line too
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        if not os.access(locked, os.W_OK):  # root may write anyway: then there is nothing to refuse
            code, _, err = _cli(capsys, "detect", scene, "-c", cal, "-o", locked / "sub" / "r.json")
            assert code == 4 and "cannot make the folder" in err
    finally:
        locked.chmod(0o700)
    with pytest.raises(OutputError, match="cannot write"):
        write_atomic(tmp_path / "file.txt", lambda fh: (_ for _ in ()).throw(OSError(28, "No space left on device")))
    assert (tmp_path / "file.txt").read_text() == "x"


def test_check_outputs_names_the_option(tmp_path):
    with pytest.raises(OutputError, match="--overlay .*cannot write images ending in '.txt'"):
        check_outputs({"--overlay": tmp_path / "o.txt"}, images=("--overlay",))
    check_outputs({"-o": tmp_path / "new" / "r.json", "--nav2": tmp_path / "nav"}, {"scene": tmp_path / "s.png"},
                  folders={"--nav2": ("map.yaml", "map.pgm")})
    with pytest.raises(OutputError, match="inside the folder of --nav2"):
        check_outputs({"-o": tmp_path / "nav" / "r.json", "--nav2": tmp_path / "nav"},
                      folders={"--nav2": ("map.yaml", "map.pgm")})
