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
import statistics
import time
from pathlib import Path

import numpy as np

HELP = "shape retrieval: Bullseye score and describe/compare times of every matcher"
DESCRIPTION = (HELP + ". DIR holds labelled silhouettes <class>-<n>.png (white on black or black on "
               "white); --make generates such a set first.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folder", nargs="?", metavar="DIR", help="folder of <class>-<n>.png silhouettes")
    parser.add_argument("--make", metavar="OUT", help="first generate a silhouette set into OUT "
                        "(and benchmark it when DIR is not given)")
    parser.add_argument("--classes", type=int, default=12, help="classes to generate with --make (default 12)")
    parser.add_argument("--per-class", type=int, default=10, help="shapes per class with --make (default 10)")
    parser.add_argument("--size", type=int, default=128, help="image size in pixels with --make (default 128)")
    parser.add_argument("--seed", type=int, default=0, help="random seed for --make (default 0)")
    parser.add_argument("--matchers", default="", help="comma-separated matcher names (default: all installed)")
    parser.add_argument("--approximator", default="", metavar="NAME",
                        help="approximate each outline by this approximator first, as the detection "
                             "pipeline does (default: match the raw pixel outlines)")
    parser.add_argument("--repeat", type=int, default=5, help="timing repetitions, the median is shown (default 5)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON instead of a table")


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
    from ..errors import InputError

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


def _median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def evaluate(matcher, outlines, labels, *, repeat: int = 5) -> dict:
    """Bullseye score and timings of one matcher instance on a loaded set."""
    n = len(outlines)
    desc = matcher.describe_many(outlines)
    dist = matcher.distance_matrix(desc, desc)
    scores = bullseye(dist, labels)
    single = []
    for _ in range(repeat):
        for p in outlines:
            t0 = time.perf_counter()
            matcher.describe(p)
            single.append(time.perf_counter() - t0)
    batch = _median_time(lambda: matcher.describe_many(outlines), repeat) / n
    pair = []
    for _ in range(repeat):
        for i in range(min(n, 50)):
            a, b = desc[i], desc[(i * 7 + 1) % n]
            t0 = time.perf_counter()
            matcher.distance(a, b)
            pair.append(time.perf_counter() - t0)
    matrix = _median_time(lambda: matcher.distance_matrix(desc, desc), repeat) / (n * n)
    return {
        "bullseye_percent": round(100 * float(scores.mean()), 2),
        "describe_us": round(1e6 * statistics.median(single), 2),
        "describe_many_us_per_shape": round(1e6 * batch, 2),
        "distance_us": round(1e6 * statistics.median(pair), 2),
        "distance_matrix_ns_per_pair": round(1e9 * matrix, 2),
        "descriptor_size": int(desc.shape[1]),
    }


def run(args: argparse.Namespace) -> int:
    import json
    import os
    import platform

    from .. import registry
    from ..errors import InputError, SbplanError
    from .silhouettes import load_silhouettes, make_silhouettes

    if args.repeat < 1:
        raise InputError(f"--repeat must be >= 1, got {args.repeat}")
    if args.make:
        make_silhouettes(args.make, classes=args.classes, per_class=args.per_class, seed=args.seed,
                         size=args.size)
    folder = args.folder or args.make
    if not folder:
        raise InputError("give a folder DIR of <class>-<n>.png silhouettes, or --make OUT to generate one")
    data = load_silhouettes(folder)
    if len(set(data.labels)) < 2:
        raise InputError(f"{folder}: needs at least two classes, found {len(set(data.labels))}")
    outlines = data.outlines
    if args.approximator:
        approx = registry.approximator(args.approximator)
        outlines = [approx.approximate(o) for o in outlines]
    names = [s.strip() for s in args.matchers.split(",") if s.strip()] or registry.matcher_names()
    from ..commands._progress import StderrProgress

    rows = []
    progress = StderrProgress("bench match")
    for k, name in enumerate(names):
        progress(k, len(names), name)
        matcher = registry.matcher(name)
        try:
            result = evaluate(matcher, outlines, data.labels, repeat=args.repeat)
        except SbplanError as exc:  # a third-party matcher that fails is reported, not fatal
            result = {"error": str(exc)}
        rows.append({"matcher": name, **result})
    progress.close()
    sizes = {lab: data.labels.count(lab) for lab in set(data.labels)}
    report = {
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
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"{report['shapes']} shapes, {report['classes']} classes in {report['folder']}; "
          f"chance Bullseye {report['chance_bullseye_percent']:.1f} %; outlines: "
          f"{args.approximator or 'raw pixels'}, {report['mean_vertices']} vertices on average")
    header = ("matcher", "Bullseye %", "describe µs", "describe_many µs/shape", "distance µs",
              "matrix ns/pair", "K")
    lines = []
    for r in rows:
        if "error" in r:
            lines.append((r["matcher"], "error: " + r["error"], "", "", "", "", ""))
            continue
        lines.append((r["matcher"], f"{r['bullseye_percent']:.1f}", f"{r['describe_us']:.1f}",
                      f"{r['describe_many_us_per_shape']:.1f}", f"{r['distance_us']:.1f}",
                      f"{r['distance_matrix_ns_per_pair']:.1f}", str(r["descriptor_size"])))
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(header)]
    print("| " + " | ".join(h.ljust(w) for h, w in zip(header, widths)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for line in lines:
        print("| " + " | ".join(v.ljust(w) for v, w in zip(line, widths)) + " |")
    return 0
