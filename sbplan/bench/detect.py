"""``sbplan bench detect``: sbplan against an ArUco marker grid and background subtraction.

For every condition of the renderer's suite (:data:`sbplan.synth.CONDITIONS`) the same seeded
scenes (same obstacles, lighting draws and noise) are rendered twice: on the symbol floor, which
sbplan and the background-subtraction baselines see, and on the ArUco marker floor
(``FloorSpec(layout="aruco")``), which the marker baseline sees. Each method is set up once per
condition from the reference image of the empty floor (sbplan: :func:`sbplan.detection.calibrate`;
baselines: :mod:`sbplan.bench.baselines`), then every frame goes image in -> occupied cells out.

Scores are cell-level precision, recall and F1 against each layout's ground truth, summed over the
condition's scenes (ambiguous cells left out). Time is the median wall-clock milliseconds of that
per-frame call over the condition's frames (each frame run ``--repeat`` times), one OpenCV thread.
Rendering and set-up are not timed.

sbplan rows: the default pipeline and, so that plugin authors see where theirs stands, the default
with one stage swapped for each other registered stage (calibrated with that stage). ``kka`` is slow
and runs on ``--slow-scenes`` frames only.

Footprints (issue 15): on the default pipeline's detections, each footprint stage (``pixels``, the
default, and ``cells``, the paper's) is scored against the true obstacles
(:func:`sbplan.bench.evaluation.score_footprints`): recall (share of the true pixels of the
obstacles the cells can see inside the reported outlines), area ratio (reported over true), the
floor points a start or goal could use that each obstacle model swallows, and the footprint
stage's CPU time per frame (``time.process_time``, median over the frames and ``--repeat`` runs:
CPU time, because the machine the figures come from is shared).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from dataclasses import replace
from typing import TYPE_CHECKING, Any, Callable, TypeVar, cast

import cv2
import numpy as np

from sbplan import registry
from sbplan.bench.baselines import AbsDiff, ArucoGrid, Mog2
from sbplan.bench.evaluation import FootprintScores, Scores, condition_scenes, score_cells, score_footprints
from sbplan.contracts import FootprintRefiner, StageChoices
from sbplan.detection import Detector
from sbplan.detection.calibration import DEFAULT_STAGES, calibrate
from sbplan.detection.obstacles import OBSTACLE_MODELS, obstacles_from_outlines
from sbplan.detection.registration import movement_at_centre
from sbplan.errors import InputError, SbplanError
from sbplan.imageio import write_image
from sbplan.synth import CONDITIONS, FloorSpec

if TYPE_CHECKING:
    from sbplan.detection.registration import CameraMotion
    from sbplan.synth.truth import GroundTruth

R = TypeVar("R")

HELP = "cell occupancy: sbplan vs ArUco grid vs background subtraction, per condition"
KINDS = ("binarizer", "extractor", "approximator", "matcher", "mapper")
#: Stages too slow for every frame: they run on --slow-scenes frames.
SLOW = {("approximator", "kka")}
BASELINES = ("aruco-grid", "absdiff", "mog2")
DEFAULT = "sbplan default"


def _pair(text: str, low: int) -> tuple[int, int]:
    try:
        a, b = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected AxB, e.g. 1280x960, got {text!r}") from None
    if a < low or b < low:
        raise argparse.ArgumentTypeError(f"expected both numbers >= {low}, got {text!r}")
    return a, b


def _size(text: str) -> tuple[int, int]:
    return _pair(text, 16)


def _grid(text: str) -> tuple[int, int]:
    return _pair(text, 1)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--conditions", nargs="+", metavar="NAME",
                        help="conditions to run (names or comma lists; default: the whole suite)")
    parser.add_argument("--scenes", type=int, default=5, help="scenes per condition (default 5)")
    parser.add_argument("--size", type=_size, default=(1280, 960), help="image size WxH (default 1280x960)")
    parser.add_argument("--grid", type=_grid, default=(10, 5), help="grid COLSxROWS (default 10x5)")
    parser.add_argument("--symbol", default="flag", metavar="NAME",
                        help="the floor's symbol, a registered one (default flag): the suite on another shape")
    parser.add_argument("--seed", type=int, default=0, help="scene seed (default 0; same for every method)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs of each frame (default 3)")
    parser.add_argument("--slow-scenes", type=int, default=1,
                        help="frames per condition for slow stages (approximator=kka; default 1)")
    parser.add_argument("--variants", choices=("all", "default"), default="all",
                        help="sbplan rows: default pipeline only, or also each single-stage swap (default all)")
    parser.add_argument("--plot", metavar="PNG", help="also draw F1 and time per condition to this PNG")
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")


def _conditions(given: list[str] | None) -> list[str]:
    if not given:
        return list(CONDITIONS)
    names = [n for g in given for n in g.split(",") if n]
    bad = [n for n in names if n not in CONDITIONS]
    if bad or not names:
        raise InputError(f"--conditions: unknown {bad or 'empty list'}; known: {', '.join(CONDITIONS)}")
    return list(dict.fromkeys(names))


def sbplan_variants(*, all_variants: bool = True) -> list[tuple[str, StageChoices]]:
    """``(label, stage overrides)``: the default pipeline, then one registered stage swapped at a time."""
    out: list[tuple[str, StageChoices]] = [(DEFAULT, {})]
    if not all_variants:
        return out
    for kind in KINDS:
        for name in getattr(registry, f"{kind}_names")():
            if name != DEFAULT_STAGES[kind]:
                out.append((f"sbplan {kind}={name}", cast(StageChoices, {kind: name})))
    return out


def _motion_error(camera: CameraMotion, truth: GroundTruth) -> tuple[float, float]:
    """How far the movement a detection reported is from the renderer's: the largest error of
    the shift (pixels) and of the rotation (degrees)."""
    m = truth.params["camera"].get("motion") or {"shift_px": [0.0, 0.0], "rotation_deg": 0.0}
    shift, rotation = m["shift_px"], m["rotation_deg"]
    if "matrix" in m:
        # the same quantity the detection reports: the true movement at the image's centre (a
        # sagged camera's tilt shifts and turns the centre too, beyond the vibration's numbers)
        floor = truth.params["floor"]
        shift, rotation, _ = movement_at_centre(np.asarray(m["matrix"]), (int(floor["height"]), int(floor["width"])))
    err_px = math.hypot(camera.shift_px[0] - shift[0], camera.shift_px[1] - shift[1])
    return err_px, abs(camera.rotation_deg - rotation)


def _timed(fn: Callable[[np.ndarray], R], image: np.ndarray, repeat: int) -> tuple[R, list[float]]:
    """``fn(image)`` run ``repeat`` (>= 1) times: its last result, and milliseconds per run."""
    runs: list[float] = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn(image)
        runs.append((time.perf_counter() - t0) * 1e3)
    return result, runs


def measure(*, conditions: list[str] | None = None, scenes: int = 5, size: tuple[int, int] = (1280, 960),
            grid: tuple[int, int] = (10, 5), seed: int = 0, repeat: int = 3, slow_scenes: int = 1,
            all_variants: bool = True, symbol: str = "flag",
            progress: Callable[[int, int, str], None] | None = None) -> dict[str, Any]:
    """Run the benchmark; return the results as a dict (what ``--json`` prints).
    ``progress(done, total, what)`` is called before each condition's set-up and each method.
    ``symbol`` names the symbol printed on the floor (a registered one; the ArUco floor is the same
    whatever it is).

    Returns
    -------
    dict
        ``rows``: one per (condition, method) with ``precision``, ``recall``, ``f1``, ``tp``,
        ``fp``, ``fn``, ``tn``, ``median_ms``, ``frames``, ``default`` (bool), ``error`` (str or
        None); ``stage_ms``: median milliseconds per stage of the default pipeline over all frames;
        ``default_with_obstacles_ms``: its median for the whole detection (obstacles included);
        ``checks``: per condition whether the default's F1 is at least every baseline's, and its
        time over the ArUco grid's; ``setup``: what was run.
    """
    names = _conditions(conditions)
    for opt, v, lo in (("--scenes", scenes, 1), ("--repeat", repeat, 1), ("--slow-scenes", slow_scenes, 0)):
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise InputError(f"{opt}: expected an integer >= {lo}, got {v!r}")
    known = registry.symbol_names()
    if symbol not in known:
        raise InputError(f"--symbol: unknown symbol {symbol!r}; registered: {', '.join(known)}")
    cv2.setNumThreads(1)
    variants = sbplan_variants(all_variants=all_variants)
    cols, rows = grid
    box = FloorSpec(width=size[0], height=size[1], cols=cols, rows=rows).symbol_size
    out_rows: list[dict] = []
    stage_ms: dict[str, list[float]] = {}
    full_ms: list[float] = []
    full_detector: Detector | None = None
    footprint_rows: list[dict] = []
    footprint_cpu: dict[str, list[float]] = {}
    per_condition = len(variants) + len(BASELINES) + 1  # the set-up, sbplan's variants, the baselines
    done = 0

    def step(what: str) -> None:
        nonlocal done
        if progress is not None:
            progress(done, len(names) * per_condition, what)
        done += 1

    for cond in names:
        step(f"{cond}: rendering and calibrating")
        sym = list(condition_scenes(cond, scenes=scenes, size=size, grid=grid, seed=seed, symbol=symbol))
        aru = list(condition_scenes(cond, scenes=scenes, size=size, grid=grid, seed=seed, layout="aruco"))
        reference, centres = sym[0][0], sym[0][2].centres_px
        methods: list[tuple[str, bool, Any, list]] = []
        for label, overrides in variants:
            try:
                det = Detector(calibrate(reference, **overrides))
                fn, err = det.find_cells, None
                if label == DEFAULT:
                    full_detector = det
            except SbplanError as exc:
                fn, err = None, f"calibration failed: {exc}"
            frames = sym[:slow_scenes] if any((k, v) in SLOW for k, v in overrides.items()) else sym
            methods.append((label, label == DEFAULT, (fn, err), frames))
        for label, make, frames in (
                ("aruco-grid", lambda: ArucoGrid(aru[0][0], rows=rows, cols=cols), aru),
                ("absdiff", lambda: AbsDiff(reference, centres, box=box), sym),
                ("mog2", lambda: Mog2(reference, centres, box=box, seed=seed), sym)):
            try:
                methods.append((label, False, (make(), None), frames))
            except SbplanError as exc:
                methods.append((label, False, (None, f"set-up failed: {exc}"), frames))
        detections = []
        for label, is_default, (fn, err), frames in methods:
            step(f"{cond}: {label}")
            total, times, motion_px, motion_deg = Scores(), [], [], []
            if fn is not None:
                for _, image, truth in frames:
                    result, runs = _timed(fn, image, repeat)
                    times += runs
                    occupied = result.occupied if hasattr(result, "occupied") else result
                    total = total + score_cells(occupied, truth.cells)
                    if is_default:
                        err_px, err_deg = _motion_error(result.camera, truth)
                        motion_px.append(err_px)
                        motion_deg.append(err_deg)
                        for k, v in result.timings_ms.items():
                            stage_ms.setdefault(k, []).append(v)
                        # issue 4's figure: the whole detection, obstacles included (the default's
                        # detector: set with its fn above, so never None here)
                        if full_detector is not None:
                            detection, runs = _timed(full_detector, image, repeat)
                            full_ms += runs
                            detections.append((image, detection, truth))
            ok = fn is not None and len(frames) > 0
            out_rows.append({
                "condition": cond, "method": label, "default": is_default, "frames": len(frames) if fn is not None else 0,
                "precision": total.precision if ok else math.nan, "recall": total.recall if ok else math.nan,
                "f1": total.f1 if ok else math.nan, "tp": total.tp, "fp": total.fp, "fn": total.fn, "tn": total.tn,
                "median_ms": float(np.median(times)) if times else math.nan, "error": err,
                # issue 14's figure: the camera movement reported against the truth, worst frame
                "motion_error_px": max(motion_px) if motion_px else math.nan,
                "motion_error_deg": max(motion_deg) if motion_deg else math.nan,
            })
            if is_default and detections:
                footprint_rows += _footprints(cond, full_detector, detections, repeat, footprint_cpu)
    checks = []
    for cond in names:
        by = {r["method"]: r for r in out_rows if r["condition"] == cond}
        d = by[DEFAULT]
        best = max(BASELINES, key=lambda m: by[m]["f1"] if not math.isnan(by[m]["f1"]) else -1)
        checks.append({
            "condition": cond, "default_f1": d["f1"], "best_baseline": best, "best_baseline_f1": by[best]["f1"],
            "f1_at_least_baselines": all(d["f1"] >= by[m]["f1"] for m in BASELINES if not math.isnan(by[m]["f1"])),
            "time_over_aruco": d["median_ms"] / by["aruco-grid"]["median_ms"],
        })
    return {
        "setup": {
            "conditions": names, "scenes": scenes, "size": list(size), "grid": list(grid), "symbol": symbol, "seed": seed,
            "repeat": repeat, "slow_scenes": slow_scenes, "threads": 1, "machine": platform.machine(),
            "python": platform.python_version(), "opencv": cv2.__version__, "numpy": np.__version__,
        },
        "rows": out_rows,
        "stage_ms": {k: float(np.median(v)) for k, v in stage_ms.items()},
        "default_with_obstacles_ms": float(np.median(full_ms)) if full_ms else math.nan,
        "checks": checks,
        "footprints": footprint_rows,
        "footprint_cpu_ms": {k: float(np.median(v)) for k, v in footprint_cpu.items()},
    }


#: The footprint stages scored: the default and the paper's.
FOOTPRINTS = ("pixels", "cells")


def _footprints(cond: str, detector, detections: list, repeat: int, cpu: dict[str, list[float]]) -> list[dict]:
    """Footprint rows of one condition: each of :data:`FOOTPRINTS` on the default pipeline's cells."""
    cal = detector.calibration
    rows = []
    for name in FOOTPRINTS:
        stage = cast(FootprintRefiner, registry.registry().create("footprint", name))
        data = stage.prepare(cal)
        if data is None and stage.fallback:
            stage = cast(FootprintRefiner, registry.registry().create("footprint", stage.fallback))
            data = stage.prepare(cal)
        total, times = FootprintScores(), []
        for image, detection, truth in detections:
            for _ in range(repeat):
                t0 = time.process_time()
                outlines = stage.outlines(image, detection.occupied, detection.occupancy, cal, detection.camera, data)
                times.append((time.process_time() - t0) * 1e3)
            obstacles = obstacles_from_outlines(outlines, detection.occupied, cal.grid, to_world=cal.pixels_to_world,
                                                to_pixels=cal.world_to_pixels)
            total = total + score_footprints(replace(detection, obstacles=obstacles), truth)
        cpu.setdefault(name, []).extend(times)
        rows.append({
            "condition": cond, "footprint": stage.name, "frames": len(detections), "recall": total.recall,
            "all_recall": total.all_recall, "area_ratio": total.area_ratio, "unseen": total.unseen,
            "free_points": total.free_points, "swallowed": dict(total.swallowed),
            "model_ratio": {m: total.model_ratio(m) for m in OBSTACLE_MODELS}, "parts_ratio": total.parts_ratio,
            "median_cpu_ms": float(np.median(times)) if times else math.nan,
        })
    return rows


def _short(method: str) -> str:
    return method.replace("sbplan ", "").replace("approximator=", "appr=").replace("binarizer=", "bin=") \
        .replace("extractor=", "ext=").replace("matcher=", "match=").replace("mapper=", "map=")


def format_tables(result: dict[str, Any]) -> str:
    """Plain-text tables: F1, median ms, precision/recall, checks, stage timings."""
    s = result["setup"]
    rows = result["rows"]
    conds = s["conditions"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    by = {(r["condition"], r["method"]): r for r in rows}
    lines = [
        f"{len(conds)} conditions x {s['scenes']} scenes, {s['size'][0]}x{s['size'][1]}, grid of "
        f"{s['grid'][0]} columns × {s['grid'][1]} rows of {s.get('symbol', 'flag')}, seed {s['seed']}; "
        f"{s['repeat']} timed runs per frame, 1 thread; "
        f"{s['machine']}, Python {s['python']}, OpenCV {s['opencv']}, numpy {s['numpy']}",
        "columns: 'default' = sbplan's default pipeline; other sbplan columns swap one stage; "
        "aruco-grid sees the ArUco floor, the rest the symbol floor",
        "",
    ]
    heads = [_short(m) for m in methods]
    widths = [max(7, len(h)) for h in heads]

    def pivot(title: str, key: str, fmt: str) -> None:
        lines.append(title)
        lines.append(f"{'condition':<11} " + " ".join(f"{h:>{w}}" for h, w in zip(heads, widths)))
        for c in conds:
            vals = []
            for m, w in zip(methods, widths):
                v = by[(c, m)][key]
                vals.append(f"{'-' if math.isnan(v) else format(v, fmt):>{w}}")
            lines.append(f"{c:<11} " + " ".join(vals))
        lines.append("")

    pivot("F1 (cells, summed over scenes)", "f1", ".3f")
    pivot("median ms per frame (image in -> occupied cells out)", "median_ms", ".2f")
    pivot("precision", "precision", ".3f")
    pivot("recall", "recall", ".3f")
    slow = sorted({m for (c, m), r in by.items() if 0 < r["frames"] < s["scenes"]})
    if slow:
        lines.append(f"on fewer frames ({s['slow_scenes']} per condition): {', '.join(slow)}")
    errs = [f"{c} / {m}: {r['error']}" for (c, m), r in by.items() if r["error"]]
    lines += errs
    lines.append("")
    lines.append("condition   default F1  best baseline       its F1  F1 >= all baselines  default ms / aruco ms  "
                 "movement error px / deg")
    for ch in result["checks"]:
        d = by[(ch["condition"], DEFAULT)]
        lines.append(f"{ch['condition']:<11} {ch['default_f1']:>10.3f}  {ch['best_baseline']:<18} "
                     f"{ch['best_baseline_f1']:>6.3f}  {'yes' if ch['f1_at_least_baselines'] else 'NO':<19}  "
                     f"{ch['time_over_aruco']:<21.3f}  {d['motion_error_px']:.3f} / {d['motion_error_deg']:.4f}")
    if result.get("footprints"):
        lines.append("")
        lines.append("footprints (default pipeline's cells; recall and area over the obstacles the cells can see; "
                     "'swallowed': free floor points inside each obstacle model's polygons; CPU ms per frame)")
        lines.append(f"{'condition':<11} {'footprint':<9} {'recall':>7} {'all':>7} {'area':>6} {'unseen':>6} "
                     f"{'parts/out':>9} {'swallowed mar/parts/outline of free':>36} {'cpu ms':>7}")
        for r in result["footprints"]:
            sw = r["swallowed"]
            lines.append(f"{r['condition']:<11} {r['footprint']:<9} {r['recall']:>7.4f} {r['all_recall']:>7.4f} "
                         f"{r['area_ratio']:>6.3f} {r['unseen']:>6d} {r['parts_ratio']:>9.3f} "
                         f"{sw.get('mar', 0):>14d}/{sw.get('parts', 0)}/{sw.get('outline', 0)} of {r['free_points']:<6d} "
                         f"{r['median_cpu_ms']:>7.2f}")
        cpu = result.get("footprint_cpu_ms", {})
        lines.append("  median CPU ms per frame over every condition: "
                     + ", ".join(f"{k} {v:.2f}" for k, v in cpu.items()))
    if result["stage_ms"]:
        lines.append("")
        lines.append("default pipeline, median ms per stage over all frames (Detector.find_cells timings):")
        lines.append("  " + "  ".join(f"{k} {v:.2f}" for k, v in result["stage_ms"].items()))
        lines.append(f"  with the occupancy image and the obstacles (Detector call, image in -> obstacles out): "
                     f"{result['default_with_obstacles_ms']:.2f}")
    return "\n".join(lines)


# -- plot (OpenCV only) ------------------------------------------------------------------------------
_COLOURS = {DEFAULT: (40, 120, 230), "aruco-grid": (60, 160, 60), "absdiff": (200, 110, 40), "mog2": (150, 60, 150)}


def plot(result: dict[str, Any], *, width: int = 1600, height: int = 1000) -> np.ndarray:
    """F1 (top) and median ms per frame (bottom, log scale) per condition, for the default pipeline
    and the three baselines. Returns a BGR image ``(height, width, 3)`` uint8."""
    conds = result["setup"]["conditions"]
    methods = [DEFAULT, *BASELINES]
    by = {(r["condition"], r["method"]): r for r in result["rows"]}
    img = np.full((height, width, 3), 255, np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    left, right, top = 110, 30, 70
    s = result["setup"]
    title = (f"sbplan bench detect: {s['size'][0]}x{s['size'][1]}, {s['grid'][0]}x{s['grid'][1]} {s.get('symbol', 'flag')}, "
             f"{s['scenes']} scene{'s' if s['scenes'] != 1 else ''} per condition, 1 thread")
    cv2.putText(img, title, (left, 35), font, 0.8, (0, 0, 0), 2, cv2.LINE_AA)
    panel_h = (height - top - 150) // 2
    plot_w = width - left - right
    group = plot_w / max(len(conds), 1)
    bar = group * 0.8 / len(methods)
    times = [by[(c, m)]["median_ms"] for c in conds for m in methods if not math.isnan(by[(c, m)]["median_ms"])]
    lo_t = 10 ** math.floor(math.log10(max(min(times, default=0.1), 1e-3)))
    hi_t = 10 ** math.ceil(math.log10(max(max(times, default=1.0), lo_t * 10)))
    span = math.log10(hi_t) - math.log10(lo_t)
    panels: list[tuple[str, str, int, Callable[[float], float], list[float], str]] = [
        ("F1", "f1", top, lambda v: v, [0, 0.25, 0.5, 0.75, 1.0], "{:.2f}"),
        ("median ms / frame (log)", "median_ms", top + panel_h + 60,
         lambda v: (math.log10(max(v, lo_t)) - math.log10(lo_t)) / span,
         [lo_t * 10 ** k for k in range(int(round(span)) + 1)], "{:g}")]
    for label, key, y0, scale, ticks, tick_fmt in panels:
        y1 = y0 + panel_h
        cv2.putText(img, label, (left, y0 - 10), font, 0.7, (0, 0, 0), 2, cv2.LINE_AA)
        for t in ticks:
            y = int(round(y1 - scale(t) * panel_h))
            cv2.line(img, (left, y), (width - right, y), (225, 225, 225), 1)
            text = tick_fmt.format(t)
            cv2.putText(img, text, (left - 12 - 13 * len(text), y + 6), font, 0.6, (60, 60, 60), 1, cv2.LINE_AA)
        cv2.line(img, (left, y1), (width - right, y1), (0, 0, 0), 1)
        cv2.line(img, (left, y0), (left, y1), (0, 0, 0), 1)
        for i, c in enumerate(conds):
            gx = left + i * group + group * 0.1
            for j, m in enumerate(methods):
                v = by[(c, m)][key]
                if math.isnan(v):
                    continue
                x0 = int(round(gx + j * bar))
                y = int(round(y1 - scale(v) * panel_h))
                cv2.rectangle(img, (x0, y), (int(round(x0 + bar)) - 1, y1), _COLOURS[m], -1)
            if key == "f1":
                continue
            target = by[(c, "aruco-grid")]["median_ms"] / 5
            if not math.isnan(target):
                # issue 6's bar: sbplan's time should stay below a fifth of the ArUco grid's
                y = int(round(y1 - scale(target) * panel_h))
                x0 = int(round(gx))
                for xd in range(x0 - 4, int(round(gx + bar)) + 4, 8):
                    cv2.line(img, (xd, y), (xd + 4, y), (0, 0, 0), 2)
            (tw, _), _ = cv2.getTextSize(c, font, 0.55, 1)
            cv2.putText(img, c, (int(left + (i + 0.5) * group - tw / 2), y1 + 24), font, 0.55, (0, 0, 0), 1,
                        cv2.LINE_AA)
    lx = left
    for m in methods:
        cv2.rectangle(img, (lx, height - 45), (lx + 24, height - 25), _COLOURS[m], -1)
        cv2.putText(img, m, (lx + 32, height - 28), font, 0.65, (0, 0, 0), 1, cv2.LINE_AA)
        lx += 60 + cv2.getTextSize(m, font, 0.65, 1)[0][0]
    for xd in range(lx, lx + 24, 8):
        cv2.line(img, (xd, height - 35), (xd + 4, height - 35), (0, 0, 0), 2)
    cv2.putText(img, "aruco-grid / 5", (lx + 32, height - 28), font, 0.65, (0, 0, 0), 1, cv2.LINE_AA)
    return img


def run(args: argparse.Namespace) -> int:
    from sbplan.commands._progress import StderrProgress

    from ._logs import camera_warnings_muted

    # the camera conditions move the camera on purpose, and the tables report each movement's error
    with camera_warnings_muted(), StderrProgress("bench detect") as progress:
        result = measure(conditions=args.conditions, scenes=args.scenes, size=args.size, grid=args.grid,
                         seed=args.seed, repeat=args.repeat, slow_scenes=args.slow_scenes,
                         all_variants=args.variants == "all", symbol=args.symbol, progress=progress)
    if args.plot:
        write_image(args.plot, plot(result))
    if args.json:
        print(json.dumps(result, indent=1, default=lambda o: None))
    else:
        print(format_tables(result))
    return 0
