"""``sbplan tui``: the operator's terminal app. Everything that imports Textual is in :mod:`sbplan.tui`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..errors import InputError, MapFormatError

HELP = "the operator's terminal app: calibrate, detect, plan and replan"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("map", nargs="?", default=None, metavar="MAP_DIR",
                        help="map folder with reference.png, scene-*.png and workspace.toml")
    parser.add_argument("--no-auto", action="store_true",
                        help="do not calibrate, detect and plan on their own; wait for the keys")
    parser.add_argument("--images", choices=("auto", "halfcell", "unicode"), default="auto",
                        help="how pictures are drawn: the terminal's graphics (sixel, kitty) when detected, "
                             "else half blocks (default: %(default)s)")


def run(args: argparse.Namespace) -> int:
    if args.map is not None and not Path(args.map).is_dir():
        if Path(args.map).exists():
            raise MapFormatError(f"{args.map}: is a file; 'sbplan tui' takes a map folder (reference.png, "
                                 "scene-*.png, workspace.toml)")
        raise MapFormatError(f"{args.map}: no such map folder")
    if not sys.stdout.isatty():
        raise InputError("tui: standard output is not a terminal; run 'sbplan tui' in a terminal")
    # imported when the command runs: the CLI starts without loading Textual
    from ..tui.launch import launch

    launch(args.map, auto=not args.no_auto, images=args.images)
    return 0
