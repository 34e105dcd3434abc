"""``sbplan bench match``: shape-retrieval accuracy (Bullseye) and speed of every installed matcher.

Bullseye convention (MPEG-7 CE-Shape-1 style): each shape is a query; all shapes, the query itself
included, are ranked by distance to it; the score of the query is the number of its class-mates
(itself included) among the first ``2 * C`` ranks divided by ``C``, the class size. The benchmark's
score is the mean over all queries, in percent. The query is put first in its own ranking even if
another shape ties at distance 0. Chance level (a random ranking) is
``(1 + (2C - 1)(C - 1)/(n - 1)) / C`` for n shapes, printed beside the scores.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import statistics
import sys
import threading
import time
from pathlib import Path
from typing import Callable, TypeVar

import numpy as np

from .. import registry
from ..errors import InputError, SbplanError
from .silhouettes import load_silhouettes, make_silhouettes

T = TypeVar("T")

HELP = "shape retrieval: Bullseye score and describe/compare times of every matcher"
DESCRIPTION = (HELP + ". Each DIR holds labelled silhouettes <class>-<n>.png (white on black or black on "
               "white; the largest outer contour is the shape), e.g. MPEG-7 CE-Shape-1; --make "
               "generates such a set first and benchmarks it too. Progress goes to stderr.")

#: Repetitions of a timing beyond the first stop once the timing has taken this long (seconds),
#: so that a matcher that needs a minute for the whole matrix is timed once, not ``--repeat`` times.
TIME_BUDGET = 10.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folders", nargs="*", metavar="DIR", help="folders of <class>-<n>.png silhouettes")
    parser.add_argument("--make", metavar="OUT", help="first generate a silhouette set into OUT and "
                        "benchmark it too")
    parser.add_argument("--classes", type=int, default=12, help="classes to generate with --make (default 12)")
    parser.add_argument("--per-class", type=int, default=10, help="shapes per class with --make (default 10)")
    parser.add_argument("--size", type=int, default=128, help="image size in pixels with --make (default 128)")
    parser.add_argument("--seed", type=int, default=0, help="random seed for --make (default 0)")
    parser.add_argument("--matchers", default="", help="comma-separated matcher names (default: all installed)")
    parser.add_argument("--approximator", default="", metavar="NAME",
                        help="approximate each outline by this approximator first, as the detection "
                             "pipeline does (default: match the raw pixel outlines)")
    parser.add_argument("--repeat", type=int, default=5,
                        help=f"timing repetitions, the median is shown (default 5; fewer where one run "
                             f"takes more than {TIME_BUDGET:.0f} s in all)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON instead of a table")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")


def bullseye(distances: np.ndarray, labels) -> np.ndarray:
    """Per-query Bullseye scores in [0, 1] (see the module docstring).

    Parameters
    ----------
    distances : ndarray of shape (n, n)
        ``distances[i, j]`` from query i to shape j.
    labels : sequence of length n
        Class of each shape.

    Returns
    -------
    ndarray of shape (n,)
    """
    d = np.array(distances, dtype=np.float64)
    n = len(labels)
    if d.shape != (n, n):
        raise InputError(f"distances: expected shape ({n}, {n}), got {d.shape}")
    lab = np.asarray(labels)
    same = lab[:, None] == lab[None, :]
    size = same.sum(axis=1)
    np.fill_diagonal(d, -np.inf)
    order = np.argsort(d, axis=1, kind="stable")
    ranked_same = np.take_along_axis(same, order, axis=1)
    hits = np.array([ranked_same[i, :min(n, 2 * size[i])].sum() for i in range(n)])
    return hits / size


def chance_level(labels) -> float:
    """Expected Bullseye score (0..1) of a random ranking."""
    lab = np.asarray(labels)
    n = len(lab)
    size = (lab[:, None] == lab[None, :]).sum(axis=1)
    k = np.minimum(n, 2 * size) - 1
    return float(np.mean((1 + k * (size - 1) / max(1, n - 1)) / size))


class _Progress:
    """One line per step on stderr, and a line every 10 s while a step runs longer."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled

    def say(self, text: str) -> None:
        if self.enabled:
            print(text, file=sys.stderr, flush=True)

    @contextlib.contextmanager
    def step(self, text: str):
        if not self.enabled:
            yield
            return

        done = threading.Event()
        t0 = time.perf_counter()

        def tick() -> None:
            while not done.wait(10.0):
                self.say(f"  ... {text}: {time.perf_counter() - t0:.0f} s")

        ticker = threading.Thread(target=tick, daemon=True)
        ticker.start()
        try:
            yield
        finally:
            done.set()
            ticker.join()
            self.say(f"  {text}: {time.perf_counter() - t0:.2f} s")


def _timed(fn: Callable[[], T]) -> tuple[float, T]:
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def _median_time(fn, repeat: int, *, first: float | None = None) -> tuple[float, int]:
    """Median of up to ``repeat`` timings of ``fn()`` (``first``, if given, is one already made),
    and how many; repetitions stop early once the timings add up to :data:`TIME_BUDGET`."""
    times = [] if first is None else [first]
    while len(times) < repeat and (not times or sum(times) < TIME_BUDGET):
        times.append(_timed(fn)[0])
    return statistics.median(times), len(times)


def evaluate(matcher, outlines, labels, *, repeat: int = 5, progress: _Progress | None = None) -> dict:
    """Bullseye score and timings of one matcher instance on a loaded set."""
    progress = progress or _Progress(False)
    n = len(outlines)
    with progress.step(f"describe_many of {n} outlines"):
        t_many, desc = _timed(lambda: matcher.describe_many(outlines))
    with progress.step(f"distance_matrix {n} x {n}"):
        cpu = time.process_time()
        t_matrix, dist = _timed(lambda: matcher.distance_matrix(desc, desc))
        cpu = time.process_time() - cpu
    scores = bullseye(dist, labels)
    with progress.step("timing"):
        few = outlines[:min(n, 100)]
        single = []
        for _ in range(repeat):
            for p in few:
                single.append(_timed(lambda: matcher.describe(p))[0])
            if sum(single) > TIME_BUDGET:
                break
        batch, _ = _median_time(lambda: matcher.describe_many(outlines), repeat, first=t_many)
        pair = []
        for _ in range(repeat):
            for i in range(min(n, 50)):
                a, b = desc[i], desc[(i * 7 + 1) % n]
                pair.append(_timed(lambda: matcher.distance(a, b))[0])
            if sum(pair) > TIME_BUDGET:
                break
        matrix, runs = _median_time(lambda: matcher.distance_matrix(desc, desc), repeat, first=t_matrix)
    return {
        "bullseye_percent": round(100 * float(scores.mean()), 2),
        "describe_us": round(1e6 * statistics.median(single), 2),
        "describe_many_us_per_shape": round(1e6 * batch / n, 2),
        "distance_us": round(1e6 * statistics.median(pair), 2),
        "distance_matrix_s": float(f"{matrix:.4g}"),
        "distance_matrix_runs": runs,
        # processor time of the first run (all threads): what the matrix costs when other
        # processes share the cores, as wall-clock timings on a busy machine do not show
        "distance_matrix_cpu_s": float(f"{cpu:.4g}"),
        "distance_matrix_ns_per_pair": round(1e9 * matrix / (n * n), 2),
        "comparisons_per_second": round(n * n / matrix, 1),
        "descriptor_size": int(desc.shape[1]),
    }


def run(args: argparse.Namespace) -> int:
    if args.repeat < 1:
        raise InputError(f"--repeat must be >= 1, got {args.repeat}")
    if args.make:
        make_silhouettes(args.make, classes=args.classes, per_class=args.per_class, seed=args.seed,
                         size=args.size)
    folders = list(args.folders) + ([args.make] if args.make else [])
    if not folders:
        raise InputError("give a folder DIR of <class>-<n>.png silhouettes, or --make OUT to generate one")
    sets = []
    for folder in folders:
        data = load_silhouettes(folder)
        if len(set(data.labels)) < 2:
            raise InputError(f"{folder}: needs at least two classes, found {len(set(data.labels))}")
        sets.append((folder, data))
    names = [s.strip() for s in args.matchers.split(",") if s.strip()] or registry.matcher_names()
    matchers = [(name, registry.matcher(name)) for name in names]  # unknown names fail before any work
    approx = registry.approximator(args.approximator) if args.approximator else None
    progress = _Progress(not args.quiet)
    reports = [_bench_set(folder, data, matchers, approx, args, progress) for folder, data in sets]
    if args.json:
        print(json.dumps(reports[0] if len(reports) == 1 else {"sets": reports}, indent=2))
        return 0
    for k, report in enumerate(reports):
        if k:
            print()
        _print_table(report, args.approximator)
    return 0


def _bench_set(folder, data, matchers, approx, args, progress: _Progress) -> dict:
    outlines = data.outlines
    if approx is not None:
        outlines = [approx.approximate(o) for o in outlines]
    sizes = {lab: data.labels.count(lab) for lab in set(data.labels)}
    progress.say(f"bench match: {folder}: {len(outlines)} shapes, {len(sizes)} classes")
    rows = []
    for k, (name, matcher) in enumerate(matchers, 1):
        progress.say(f"[{k}/{len(matchers)}] {name}")
        try:
            result = evaluate(matcher, outlines, data.labels, repeat=args.repeat, progress=progress)
        except SbplanError as exc:  # a third-party matcher that fails is reported, not fatal
            result = {"error": str(exc)}
        rows.append({"matcher": name, **result})
    return {
        "folder": str(Path(folder)),
        "shapes": len(data.labels),
        "classes": len(sizes),
        "class_sizes": sorted(set(sizes.values())),
        "approximator": args.approximator or None,
        "mean_vertices": round(float(np.mean([len(o) for o in outlines])), 1),
        "chance_bullseye_percent": round(100 * chance_level(data.labels), 2),
        "bullseye_convention": "query included, class-mates among the first 2*C ranks divided by C",
        "machine": {"cores": os.cpu_count(), "python": platform.python_version()},
        "results": rows,
    }


def _print_table(report: dict, approximator: str) -> None:
    print(f"{report['shapes']} shapes, {report['classes']} classes in {report['folder']}; "
          f"chance Bullseye {report['chance_bullseye_percent']:.1f} %; outlines: "
          f"{approximator or 'raw pixels'}, {report['mean_vertices']} vertices on average")
    header = ("matcher", "Bullseye %", "describe µs", "describe_many µs/shape", "distance µs",
              "matrix s", "comparisons/s", "K")
    lines = []
    for r in report["results"]:
        if "error" in r:
            lines.append((r["matcher"], "error: " + r["error"], "", "", "", "", "", ""))
            continue
        lines.append((r["matcher"], f"{r['bullseye_percent']:.1f}", f"{r['describe_us']:.1f}",
                      f"{r['describe_many_us_per_shape']:.1f}", f"{r['distance_us']:.1f}",
                      f"{r['distance_matrix_s']:.3g}", f"{r['comparisons_per_second']:.3g}",
                      str(r["descriptor_size"])))
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(header)]
    print("| " + " | ".join(h.ljust(w) for h, w in zip(header, widths)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for line in lines:
        print("| " + " | ".join(v.ljust(w) for v, w in zip(line, widths)) + " |")
