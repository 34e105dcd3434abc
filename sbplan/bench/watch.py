"""``sbplan bench watch``: the live pipeline's speed, with and without decoding, one and many streams.

For each size, the renderer's test stream (:func:`sbplan.synth.sequence.demo_sequence`: obstacles
entering, sliding and leaving, a person's shadow, a camera bump, a dropped, a corrupt and a damaged
frame) is rendered once, kept in memory and written as an MJPG AVI; a calibration is made on its
reference. Then, with one OpenCV thread:

- **detection alone**: ``Detector.find_cells`` on every fifth frame, 10 times each; the least CPU
  time of the 10 is what the frame costs when nothing else disturbs the core.
- **throughput** (frames as fast as the pipeline takes them, every frame): frames in memory through
  :class:`sbplan.live.Watcher` (no decoding), as the watch runs by default (a frame that did not
  change is not detected again, one that changed in part has only the cells near the change
  detected again), the same with changed frames detected whole (``--whole-frames``), and with every
  frame detected (``--every-frame``); the AVI through
  ``cv2.VideoCapture`` and the same pipeline (decoding in the reader thread); decoding alone.
  Frames per second of wall-clock time, and CPU milliseconds per frame (``time.thread_time`` of
  the pipeline's thread; process CPU time when decoding runs beside it).
- **live at --fps**: the frames delivered at the stream's rate as a camera would (the reader keeps
  the latest frame): frames processed and dropped, median and 99th-percentile latency from a
  frame's capture to the end of its processing (what every event of that frame reports);
  from memory and from the AVI.
- **--streams streams on one core**: that many watches at --fps in threads of one process pinned
  to one CPU (``os.sched_setaffinity``), frames from memory: per stream, frames processed and
  dropped and latency; CPU per stream as a share of the core. Twice: all streams the same stream
  in step (every change comes to all at once: the worst case), then each stream a few frames
  behind the last (as independent cameras).

The machine may be shared: wall-clock figures (fps, latency, drops) then suffer; CPU time per
frame much less, and it decides whether N streams at F fps fit one core (N x F x CPU/frame <= 1 s).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import tempfile
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Literal, Sequence

import cv2
import numpy as np

from sbplan.detection import Detector
from sbplan.detection.calibration import calibrate
from sbplan.errors import InputError
from sbplan.live import IterableSource, VideoSource, Watcher, paced
from sbplan.synth import FloorSpec
from sbplan.synth.sequence import demo_sequence, render_sequence, write_sequence

if TYPE_CHECKING:
    from sbplan.detection.calibration import Calibration
    from sbplan.live import Source
    from sbplan.live.watcher import WatchStats

HELP = "live pipeline (sbplan watch): fps with and without decoding, latency, streams per core"


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WxH, e.g. 1280x960, got {text!r}") from None
    if w < 160 or h < 120:
        raise argparse.ArgumentTypeError(f"expected at least 160x120, got {text!r}")
    return w, h


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--sizes", nargs="+", type=_size, default=[(1280, 960), (1920, 1080)], metavar="WxH",
                        help="frame sizes (default 1280x960 1920x1080)")
    parser.add_argument("--frames", type=int, default=60, help="frames of the rendered stream (default 60)")
    parser.add_argument("--loops", type=int, default=3, help="times the stream is played in each run (default 3)")
    parser.add_argument("--fps", type=float, default=30.0, help="rate of the live runs (default 30)")
    parser.add_argument("--streams", type=int, default=8, help="streams sharing one core (default 8; 0: skip)")
    parser.add_argument("--hysteresis", default="3", help="hysteresis of the watches (default 3 frames)")
    parser.add_argument("--seed", type=int, default=0, help="stream seed (default 0)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")


def _grid(size: tuple[int, int]) -> tuple[int, int]:
    """About 128 x 120 px cells, as the renderer's default 10 x 8 at 1280 x 960."""
    return max(4, round(size[0] / 128)), max(3, round(size[1] / 120))


def _stream(size: tuple[int, int], frames: int, seed: int,
            folder: Path) -> tuple[FloorSpec, list[np.ndarray], Path, Calibration]:
    cols, rows = _grid(size)
    floor = FloorSpec(width=size[0], height=size[1], cols=cols, rows=rows)
    spec = demo_sequence(floor, n_frames=frames, fps=30.0)
    avi = write_sequence(folder, floor, spec, seed=seed, kind="avi")
    images = [img for k, img, t in render_sequence(floor, spec, seed=seed) if not t["dropped"] and not t["corrupt"]]
    cal = calibrate(str(folder / "reference.png"))
    return floor, images, avi, cal


def _watch(source: Source, cal: Calibration, *, hysteresis: str, **options: Any) -> tuple[WatchStats, float, float]:
    """Run one watch to its end: (stats, wall seconds, process CPU seconds)."""
    w = Watcher(source, cal, hysteresis=hysteresis, stall_timeout=30.0, **options)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in w.events():
        pass
    return w.stats(), time.perf_counter() - t0, time.process_time() - c0


def _decode_only(avi: Path) -> tuple[int, float, float]:
    cap = cv2.VideoCapture(str(avi), cv2.CAP_FFMPEG)
    n, t0, c0 = 0, time.perf_counter(), time.thread_time()
    fails = 0
    while fails < 3:
        ok, image = cap.read()
        if not ok:
            fails += 1
            continue
        cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)  # as the reader hands frames over
        n += 1
    cap.release()
    return n, time.perf_counter() - t0, time.thread_time() - c0


def measure(*, sizes: Sequence[tuple[int, int]] = ((1280, 960), (1920, 1080)), frames: int = 60, loops: int = 3,
            fps: float = 30.0, streams: int = 8, hysteresis: str = "3", seed: int = 0,
            workdir: str | os.PathLike[str] | None = None,
            progress: Callable[[int, int, str], None] | None = None) -> dict[str, Any]:
    """Run the benchmark; the results as a dict (what ``--json`` prints). ``progress(done,
    total, what)`` is called before each part of each size."""
    for name, v, lo in (("--frames", frames, 24), ("--loops", loops, 1), ("--streams", streams, 0)):
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise InputError(f"{name}: expected an integer >= {lo}, got {v!r}")
    if not (isinstance(fps, (int, float)) and 0 < fps <= 240):
        raise InputError(f"--fps: expected a number in (0, 240], got {fps!r}")
    cv2.setNumThreads(1)
    rows = []
    parts = 6 if streams else 5
    done = 0

    def step(what: str) -> None:
        nonlocal done
        if progress is not None:
            progress(done, parts * len(sizes), what)
        done += 1

    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        for size in sizes:
            at = f"{size[0]}x{size[1]}"
            step(f"{at}: rendering the stream and calibrating")
            floor, images, avi, cal = _stream(size, frames, seed, Path(tmp) / f"{size[0]}x{size[1]}")
            played = images * loops
            row: dict[str, Any] = {"size": list(size), "grid": [floor.cols, floor.rows], "frames": len(played)}

            def mem(live_rate: float | None = None) -> Source:
                src = IterableSource(played, live=False, fps=fps)
                return paced(src) if live_rate else src

            # detection of one frame on its own, each frame repeated: the least CPU of the repeats is
            # close to what a quiet machine takes (others' load only ever adds)
            step(f"{at}: detection of single frames")
            det = Detector(cal)
            per_frame = []
            for image in images[::5]:
                runs = []
                for _ in range(10):
                    c0 = time.thread_time()
                    det.find_cells(image)
                    runs.append(time.thread_time() - c0)
                per_frame.append((min(runs), float(np.median(runs))))
            row["detect_cpu_ms"] = {"min_of_10": 1e3 * float(np.median([a for a, _ in per_frame])),
                                    "median": 1e3 * float(np.median([b for _, b in per_frame]))}
            # throughput, no decoding: as the watch runs, and every frame detected
            step(f"{at}: throughput from memory")
            for key, skip, local in (("memory", True, True), ("memory_whole", True, False),
                                     ("memory_every_frame", False, False)):
                st, wall, cpu = _watch(mem(), cal, hysteresis=hysteresis, latest=False, skip_unchanged=skip, local=local)
                row[key] = {"fps": st["frames_processed"] / wall, "cpu_ms_per_frame": st["cpu_ms_per_frame"],
                            "frames": st["frames_processed"], "unchanged": st["frames_unchanged"],
                            "local": st["frames_local"]}
            # throughput with decoding (AVI through cv2.VideoCapture), and decoding alone
            step(f"{at}: throughput decoding the AVI")
            n_dec, wall_dec, cpu_dec = 0, 0.0, 0.0
            st_all = []
            for _ in range(loops):
                st, wall, cpu = _watch(VideoSource(str(avi)), cal, hysteresis=hysteresis, latest=False)
                st_all.append((st, wall, cpu))
                n, w2, c2 = _decode_only(avi)
                n_dec, wall_dec, cpu_dec = n_dec + n, wall_dec + w2, cpu_dec + c2
            n_avi = sum(s["frames_processed"] for s, _, _ in st_all)
            row["avi"] = {"fps": n_avi / sum(w for _, w, _ in st_all),
                          "cpu_ms_per_frame": 1e3 * sum(c for _, _, c in st_all) / n_avi,
                          "pipeline_cpu_ms_per_frame": float(np.mean([s["cpu_ms_per_frame"] for s, _, _ in st_all]))}
            row["decode_only"] = {"fps": n_dec / wall_dec, "cpu_ms_per_frame": 1e3 * cpu_dec / n_dec}
            # live at fps: one stream, from memory and from the AVI
            step(f"{at}: live at {fps:g} fps")
            for key, source in (("live_memory", paced(IterableSource(played, live=False, fps=fps))),
                                ("live_avi", paced(VideoSource(str(avi)), speed=fps / 30.0))):
                st, wall, cpu = _watch(source, cal, hysteresis=hysteresis)
                row[key] = {"processed": st["frames_processed"], "dropped": st["frames_dropped"],
                            "read": st["frames_read"], "latency_ms": st["latency_ms"],
                            "cpu_ms_per_frame": st["cpu_ms_per_frame"], "process_cpu_share": cpu / wall}
            if streams:
                step(f"{at}: {streams} streams at once")
                row["streams"] = _streams(played, cal, n=streams, fps=fps, hysteresis=hysteresis)
                # the same streams out of step: a real site's cameras do not all change at once
                row["streams_staggered"] = _streams(played, cal, n=streams, fps=fps, hysteresis=hysteresis,
                                                    stagger=max(1, len(images) // streams))
            rows.append(row)
    return {"setup": {"sizes": [list(s) for s in sizes], "frames": frames, "loops": loops, "fps": fps,
                      "streams": streams, "hysteresis": hysteresis, "seed": seed, "opencv_threads": 1,
                      "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
                                 f"OpenCV {cv2.__version__}, numpy {np.__version__}",
                      "load_average": list(os.getloadavg())},
            "rows": rows}


def _streams(frames: list[np.ndarray], cal: Calibration, *, n: int, fps: float, hysteresis: str,
             stagger: int = 0) -> dict[str, Any]:
    """``n`` watches at ``fps`` in threads of this process, pinned to one core; with ``stagger``,
    stream ``i`` plays the frames from frame ``i * stagger`` on (and the first ones last)."""
    watchers = [Watcher(paced(IterableSource(frames[i * stagger:] + frames[:i * stagger], live=False, fps=fps)), cal,
                        hysteresis=hysteresis, stall_timeout=30.0) for i in range(n)]
    before = os.sched_getaffinity(0) if hasattr(os, "sched_setaffinity") else None
    pinned = before is not None
    if before is not None:
        os.sched_setaffinity(0, {min(before)})
    try:
        threads = [threading.Thread(target=lambda w=w: [None for _ in w.events()]) for w in watchers]
        t0, c0 = time.perf_counter(), time.process_time()
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        if before is not None:
            os.sched_setaffinity(0, before)
    stats = [w.stats() for w in watchers]
    return {"n": n, "stagger": stagger, "pinned_to_one_core": pinned, "wall_s": wall, "process_cpu_share": cpu / wall,
            "processed": [s["frames_processed"] for s in stats], "dropped": [s["frames_dropped"] for s in stats],
            "read": [s["frames_read"] for s in stats],
            "latency_median_ms": [_latency(s, "median") for s in stats],
            "latency_p99_ms": [_latency(s, "p99") for s in stats],
            "cpu_ms_per_frame": [s["cpu_ms_per_frame"] for s in stats]}


def _latency(stats: WatchStats, which: Literal["median", "p99"]) -> float:
    """A watch's median or 99th-percentile latency, ms (NaN for a watch that processed no frame)."""
    lat = stats["latency_ms"]
    return math.nan if lat is None else lat[which]


def format_tables(result: dict[str, Any]) -> str:
    s = result["setup"]
    budget = 1e3 / (s["fps"] * max(s["streams"], 1))
    lines = [f"{s['frames']}-frame stream x {s['loops']} loops; live runs at {s['fps']:g} fps; hysteresis {s['hysteresis']}; "
             f"1 OpenCV thread; {s['machine']}; load average {', '.join(f'{v:.2f}' for v in s['load_average'])}",
             ""]
    for r in result["rows"]:
        w, h = r["size"]
        lines.append(f"{w}x{h}, grid of {r['grid'][0]} columns × {r['grid'][1]} rows, {r['frames']} frames per run")
        lines.append(f"  {'throughput (every frame, as fast as it goes)':<52} {'fps':>8} {'CPU ms/frame':>13}")
        m, e, a, d = r["memory"], r["memory_every_frame"], r["avi"], r["decode_only"]
        lines.append(f"  {'no decoding, as watched (unchanged frames reused)':<52} {m['fps']:8.1f} {m['cpu_ms_per_frame']:13.2f}"
                     f"   ({m['unchanged']} of {m['frames']} frames unchanged, {m['local']} detected in part)")
        if "memory_whole" in r:
            mw = r["memory_whole"]
            lines.append(f"  {'  the same, changed frames detected whole':<52} {mw['fps']:8.1f} {mw['cpu_ms_per_frame']:13.2f}")
        lines.append(f"  {'no decoding, every frame detected':<52} {e['fps']:8.1f} {e['cpu_ms_per_frame']:13.2f}")
        lines.append(f"  {'AVI: decoding + pipeline (process CPU)':<52} {a['fps']:8.1f} {a['cpu_ms_per_frame']:13.2f}"
                     f"   (pipeline thread {a['pipeline_cpu_ms_per_frame']:.2f})")
        lines.append(f"  {'decoding alone (MJPG, cv2.VideoCapture)':<52} {d['fps']:8.1f} {d['cpu_ms_per_frame']:13.2f}")
        dc = r["detect_cpu_ms"]
        lines.append(f"  {'one frame detected (find_cells), 10 repeats: least':<52} {'':>8} {dc['min_of_10']:13.2f}"
                     f"   (median {dc['median']:.2f})")
        lines.append(f"  {'live at ' + format(s['fps'], 'g') + ' fps, one stream':<52} {'processed':>10} {'dropped':>8} "
                     f"{'median ms':>10} {'p99 ms':>8}")
        for key, label in (("live_memory", "frames from memory"), ("live_avi", "frames decoded from the AVI")):
            v = r[key]
            lines.append(f"  {'  ' + label:<52} {v['processed']:>10} {v['dropped']:>8} {v['latency_ms']['median']:>10.2f} "
                         f"{v['latency_ms']['p99']:>8.2f}")
        for st in (r[k] for k in ("streams", "streams_staggered") if k in r):
            cpu = np.array(st["cpu_ms_per_frame"], float)
            step = (f", each {st['stagger']} frames behind the last" if st.get("stagger") else
                    ", all the same stream in step")
            lines.append(f"  {st['n']} streams at {s['fps']:g} fps on one core ({'pinned' if st['pinned_to_one_core'] else 'NOT pinned'}), "
                         f"frames from memory{step}: process CPU {100 * st['process_cpu_share']:.0f} % of a core")
            lines.append(f"    processed per stream {min(st['processed'])}..{max(st['processed'])} of {r['frames']}, dropped "
                         f"{min(st['dropped'])}..{max(st['dropped'])}; latency median {np.median(st['latency_median_ms']):.2f} ms, "
                         f"p99 {max(st['latency_p99_ms']):.2f} ms (worst stream)")
            lines.append(f"    CPU ms per processed frame {np.median(cpu):.2f} (budget for {st['n']} x {s['fps']:g} fps: "
                         f"{budget:.2f}); CPU per stream {100 * st['process_cpu_share'] / st['n']:.1f} % of the core")
        lines.append("")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from ..commands._progress import StderrProgress
    from ._logs import camera_warnings_muted

    # the stream bumps the camera on purpose: one warning per stream's detector would follow
    with camera_warnings_muted(), StderrProgress("bench watch") as progress:
        result = measure(sizes=args.sizes, frames=args.frames, loops=args.loops, fps=args.fps,
                         streams=args.streams, hysteresis=args.hysteresis, seed=args.seed, progress=progress)
    if args.json:
        print(json.dumps(result, indent=1, default=lambda o: None))
    else:
        print(format_tables(result))
    return 0
