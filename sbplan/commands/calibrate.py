"""``sbplan calibrate``: fit the symbol grid and the match threshold on the empty floor."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._stage_options import add_stage_arguments, stage_choices

HELP = "calibrate on a reference image of the empty floor and write a calibration file"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("reference", help="reference image (empty floor, every symbol visible)")
    parser.add_argument("-o", "--output", required=True, help="calibration file to write (JSON, atomically)")
    parser.add_argument("--symbol", help="an image of one reference symbol (default: the most repeated shape)")
    scale = parser.add_mutually_exclusive_group()
    scale.add_argument("--cell-size", type=float, metavar="METRES", help="grid pitch in metres")
    scale.add_argument("--workspace", metavar="TOML",
                       help="workspace.toml (default: the one beside the reference image, if any)")
    add_stage_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from ..detection.calibration import calibrate

    workspace = args.workspace
    if workspace is None and args.cell_size is None:
        beside = Path(args.reference).parent / "workspace.toml"
        workspace = beside if beside.is_file() else None
    cal = calibrate(args.reference, symbol=args.symbol, workspace=workspace, cell_size=args.cell_size,
                    **stage_choices(args))
    cal.save(args.output)
    g = cal.grid
    dx, dy = g.pitch_px
    print(f"grid {g.cols} x {g.rows} ({cal.symbols_expected} symbols), pitch {dx:.1f} x {dy:.1f} px, "
          f"tolerance {g.tolerance_px:.1f} px")
    print(f"match threshold {cal.threshold:.4f} ({cal.stages['matcher']['name']}), margin {cal.margin:.1f}x "
          f"(nearest other contour / farthest symbol)")
    print(f"wrote {args.output}")
    return 0
