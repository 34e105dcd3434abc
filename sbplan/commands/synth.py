"""``sbplan synth``: render synthetic floors (reference, scenes, ground truth) and the example maps."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from ..errors import InputError, SceneError

HELP = "render a synthetic floor with obstacles and ground truth, or rebuild an example map"
#: ``sbplan synth`` alone prints this command's help (it needs -o, --map or --list).
BARE_HELP = True
DESCRIPTION = ("Render reference.png (the empty floor), scene-XX.png with obstacles and scene-XX.json ground "
               "truth into a folder; or a camera stream with per-frame truth (--sequence avi|folder: obstacles "
               "entering, moving and leaving, a person's shadow, a camera bump, dropped and corrupt frames); or "
               "rebuild a named map exactly (--map); or list maps and conditions (--list).")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-o", "--output", metavar="DIR",
                        help="output folder (required unless --map or --list; --map default: maps/NAME)")
    parser.add_argument("--map", metavar="NAME", help="rebuild a named example map (see --list)")
    parser.add_argument("--list", action="store_true", help="list the example maps and the conditions")
    parser.add_argument("--size", default="1280x960", metavar="WxH", help="image size in pixels (default: %(default)s)")
    parser.add_argument("--grid", default="10x8", metavar="CxR", help="columns x rows of symbols (default: %(default)s)")
    parser.add_argument("--symbol", default=None, metavar="NAME", help="registered symbol (default: the default symbol)")
    parser.add_argument("--scenes", type=int, default=1, metavar="N", help="number of scenes (default: %(default)s)")
    parser.add_argument("--obstacles", type=int, default=3, metavar="N", help="obstacles per scene (default: %(default)s)")
    parser.add_argument("--condition", default="clean", metavar="NAME",
                        help="adverse condition of the scenes (default: %(default)s; see --list)")
    parser.add_argument("--sequence", choices=("avi", "folder"), metavar="KIND",
                        help="write a stream instead of scenes: avi (MJPG video) or folder (PNG frames), with "
                             "reference.png, truth.jsonl and sequence.json (see docs/live.md)")
    parser.add_argument("--frames", type=int, default=48, metavar="N", help="frames of a --sequence (default: %(default)s)")
    parser.add_argument("--fps", type=float, default=10.0, metavar="F",
                        help="frame rate of a --sequence (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="seed: floor texture and reference noise use S, scene k uses S + k (default: %(default)s)")


def _pair(text: str, option: str, sep: str = "x") -> tuple[int, int]:
    m = re.fullmatch(rf"\s*(-?\d+)\s*{sep}\s*(-?\d+)\s*", text or "")
    if not m:
        raise InputError(f"{option}: expected two integers like 1280{sep}960, got {text!r}")
    return int(m.group(1)), int(m.group(2))


def run(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and the pipeline
    from ..files import write_folder
    from ..imageio import write_atomic, write_image
    from ..synth import CONDITIONS, DEFAULT_SYMBOL, FloorSpec, SceneSpec, render_reference, render_scene
    from ..synth.maps import MAPS, build_map

    if args.list:
        print("maps (sbplan synth --map NAME):")
        width = max(map(len, MAPS))
        for name, desc in MAPS.items():
            print(f"  {name:<{width}}  {desc}")
        print("conditions (--condition NAME):")
        width = max(map(len, CONDITIONS))
        for name, desc in CONDITIONS.items():
            print(f"  {name:<{width}}  {desc}")
        return 0
    if args.map:
        folder = build_map(args.map, args.output)
        print(f"wrote {folder}/ ({', '.join(sorted(p.name for p in folder.iterdir() if not p.name.startswith('.')))})")
        return 0
    if not args.output:
        raise InputError("--output: give an output folder (-o DIR), or --map NAME, or --list")
    width, height = _pair(args.size, "--size")
    cols, rows = _pair(args.grid, "--grid")
    if args.scenes < 0:
        raise SceneError(f"--scenes: must be >= 0, got {args.scenes}")
    if args.seed < 0:
        raise SceneError(f"--seed: must be >= 0, got {args.seed}")
    floor = FloorSpec(width=width, height=height, cols=cols, rows=rows, symbol=args.symbol or DEFAULT_SYMBOL,
                      floor_seed=args.seed)
    out = Path(args.output)
    if args.sequence:
        from ..synth.sequence import demo_sequence, write_sequence

        spec = demo_sequence(floor, n_frames=args.frames, fps=args.fps, condition=args.condition)
        stream = write_sequence(out, floor, spec, seed=args.seed, kind=args.sequence)
        print(f"wrote {out}/: reference.png, {stream.name}{'/' if args.sequence == 'folder' else ''}, truth.jsonl, "
              f"sequence.json ({args.frames} frames at {args.fps:g} fps, {cols} x {rows} symbols, {width} x {height} px, "
              f"condition {args.condition})")
        return 0
    scene = SceneSpec(n_obstacles=args.obstacles, condition=args.condition)

    def fill(tmp: Path) -> None:
        write_image(tmp / "reference.png", render_reference(floor, seed=args.seed, condition=args.condition))
        for k in range(1, args.scenes + 1):
            img, truth = render_scene(floor, scene, seed=args.seed + k)
            write_image(tmp / f"scene-{k:02d}.png", img)
            write_atomic(tmp / f"scene-{k:02d}.json", truth.to_json())
            c = truth.counts
            print(f"scene-{k:02d}: {c['occupied']} occupied, {c['ambiguous']} ambiguous, {c['free']} free cells")

    # one unit: a rerun with other options or fewer scenes leaves no scene of the old run beside
    # the new reference, and a killed run leaves the old folder whole
    write_folder(out, fill, names=lambda name: re.fullmatch(r"reference\.png|scene-\d+\.(png|json)", name) is not None)
    print(f"wrote {out}/: reference.png and {args.scenes} scene(s) ({cols} columns × {rows} rows of symbols, "
          f"{width} x {height} px, "
          f"condition {args.condition})")
    return 0
