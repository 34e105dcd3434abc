"""``sbplan bench stages``: time every registered extractor, approximator and matcher on one frame.

The frame is a 1280x960 grayscale reference floor with 10 x 5 = 50 symbols rendered by
:mod:`sbplan.synth` (or, if that module is unavailable, 50 copies of an asymmetric polygon drawn
with ``cv2.fillPoly`` on a light, seeded noisy floor). It is binarized once with
``cv2.adaptiveThreshold`` (mean of a 51-pixel block minus 10, dark ink = foreground). Then, each
``--repeat`` times on one core (``cv2.setNumThreads(1)``):

- each extractor on the whole binary frame;
- each approximator on the 50 longest outer contours (the symbols);
- each matcher's ``describe_many`` on the 50 polygons (Douglas-Peucker, or the first approximator
  registered) and ``distance_matrix`` of those 50 descriptors against one reference (50 x 1).
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from typing import Any, Callable

import cv2
import numpy as np

from sbplan import registry
from sbplan.errors import InputError

HELP = "time contour extraction, approximation and descriptors on a 1280x960 floor"
N_SYMBOLS = 50


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--repeat", type=int, default=30, help="timed runs per stage (default 30)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the rendered floor (default 0)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")


def floor_image(*, seed: int = 0) -> tuple[np.ndarray, str]:
    """The benchmark frame, shape (960, 1280) uint8, and how it was made."""
    try:  # here, not at the top: the fallback frame serves an installation without sbplan.synth
        from sbplan.synth import FloorSpec, render_reference
    except ImportError:
        return _fallback_floor(seed=seed), "cv2.fillPoly fallback, 50 symbols"
    floor = FloorSpec(width=1280, height=960, cols=10, rows=5)
    return render_reference(floor, seed=seed), "sbplan.synth.render_reference, 10 x 5 symbols"


def _fallback_floor(*, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.full((960, 1280), 200.0)
    symbol = np.array([[0, 0], [1, 0], [1, 0.35], [0.4, 0.35], [0.4, 1], [0, 1]]) * 60 - 30
    for row in range(5):
        for col in range(10):
            centre = np.array([64 + 128 * col, 96 + 192 * row])
            cv2.fillPoly(img, [np.round(symbol + centre).astype(np.int32)], 40.0)
    img += rng.normal(0, 4, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def binarize(gray: np.ndarray) -> np.ndarray:
    """Dark ink as foreground (uint8 0/255), by local mean thresholding."""
    return cv2.adaptiveThreshold(gray, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, 51, 10)


def _time(fn: Callable[[], Any], repeat: int) -> dict[str, float]:
    fn()  # warm-up: first-call imports and caches are not what is measured
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        runs.append((time.perf_counter() - t0) * 1e3)
    return {"median_ms": float(np.median(runs)), "p90_ms": float(np.percentile(runs, 90))}


def measure(*, repeat: int = 30, seed: int = 0,
            progress: Callable[[int, int, str], None] | None = None) -> dict[str, Any]:
    """Run the benchmark and return its results as a dict (what ``--json`` prints);
    ``progress(done, total, what)`` is called before each stage is timed."""
    if repeat < 1:
        raise InputError(f"--repeat: must be at least 1, got {repeat}")
    cv2.setNumThreads(1)
    gray, source = floor_image(seed=seed)
    binary = binarize(gray)
    rows: list[dict[str, Any]] = []

    reference = registry.extractor("opencv").extract(binary)
    outers = sorted((c for c in reference if not c.is_hole), key=len, reverse=True)[:N_SYMBOLS]
    steps = [("extractor", n) for n in registry.extractor_names()] + \
        [("approximator", n) for n in registry.approximator_names()] + [("matcher", n) for n in registry.matcher_names()]
    done = iter(range(len(steps)))

    def step(kind: str, name: str) -> None:
        if progress is not None:
            progress(next(done), len(steps), f"{kind} {name}")

    for name in registry.extractor_names():
        step("extractor", name)
        ex = registry.extractor(name)
        count = len(ex.extract(binary))
        rows.append({"stage": "extractor", "name": name, "work": f"1280x960 frame -> {count} contours",
                     **_time(lambda: ex.extract(binary), repeat)})
        if name in ("opencv", "oke"):
            fast = type(ex)(chains=False)
            rows.append({"stage": "extractor", "name": f"{name} chains=False", "work": "same, no chains",
                         **_time(lambda: fast.extract(binary), repeat)})

    polygons: dict[str, list[np.ndarray]] = {}
    for name in registry.approximator_names():
        step("approximator", name)
        ap = registry.approximator(name)
        polygons[name] = [ap.approximate(c) for c in outers]
        rows.append({"stage": "approximator", "name": name, "work": f"{len(outers)} contours",
                     **_time(lambda: [ap.approximate(c) for c in outers], repeat)})
    polys = polygons.get("douglas-peucker") or next(iter(polygons.values()), None)
    if polys is None:  # no approximator registered: describe the pixel outlines themselves
        polys = [c.points.astype(np.float64) for c in outers]

    for name in registry.matcher_names():
        step("matcher", name)
        m = registry.matcher(name)
        desc = m.describe_many(polys)
        ref = desc[:1]
        rows.append({"stage": "matcher", "name": f"{name} describe_many", "work": f"{len(polys)} polygons",
                     **_time(lambda: m.describe_many(polys), repeat)})
        rows.append({"stage": "matcher", "name": f"{name} distance_matrix", "work": f"{len(polys)} x 1",
                     **_time(lambda: m.distance_matrix(desc, ref), repeat)})

    return {
        "benchmark": "stages",
        "frame": source,
        "binarization": "cv2.adaptiveThreshold MEAN_C, block 51, C 10, inverted",
        "symbol_contours": len(outers),
        "repeat": repeat,
        "threads": 1,
        "machine": f"{platform.machine()}, Python {platform.python_version()}, OpenCV {cv2.__version__}, "
                   f"numpy {np.__version__}",
        "rows": rows,
    }


def format_table(result: dict[str, Any]) -> str:
    lines = [f"frame: {result['frame']}; binarized by {result['binarization']}",
             f"{result['symbol_contours']} symbol contours; {result['repeat']} runs each, 1 thread; "
             f"{result['machine']}", ""]
    header = ("stage", "name", "work", "median ms", "p90 ms")
    table = [header] + [(r["stage"], r["name"], r["work"], f"{r['median_ms']:.3f}", f"{r['p90_ms']:.3f}")
                        for r in result["rows"]]
    widths = [max(len(row[i]) for row in table) for i in range(len(header))]
    for k, row in enumerate(table):
        lines.append("  ".join(cell.ljust(widths[i]) if i < 3 else cell.rjust(widths[i])
                               for i, cell in enumerate(row)).rstrip())
        if k == 0:
            lines.append("  ".join("-" * wd for wd in widths))
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from ..commands._progress import StderrProgress

    with StderrProgress("bench stages") as progress:
        result = measure(repeat=args.repeat, seed=args.seed, progress=progress)
    print(json.dumps(result, indent=2) if args.json else format_table(result))
    return 0
