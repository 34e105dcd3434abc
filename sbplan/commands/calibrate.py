"""``sbplan calibrate``: fit the symbol grid and the match threshold on the empty floor."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import InputError
from ._stage_options import add_stage_arguments, stage_choices

HELP = "calibrate on a reference image of the empty floor and write a calibration file"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("reference", help="reference image (empty floor, every symbol visible); with --update, "
                                          "a current frame from the moved camera (obstacles allowed)")
    parser.add_argument("-o", "--output", help="calibration file to write (JSON, atomically); "
                                               "with --update the default is the updated file itself")
    parser.add_argument("--update", metavar="CALIBRATION",
                        help="re-anchor this calibration to the camera's present pose from the frame given "
                             "(the free symbols are used; the file stays as it was if that fails)")
    parser.add_argument("--symbol", help="an image of one reference symbol (default: the most repeated shape)")
    scale = parser.add_mutually_exclusive_group()
    scale.add_argument("--cell-size", type=float, metavar="METRES", help="grid pitch in metres")
    scale.add_argument("--workspace", metavar="TOML",
                       help="workspace.toml (default: the one beside the reference image, if any)")
    add_stage_arguments(parser)


def run(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and the pipeline
    from ..detection.calibration import calibrate, load_calibration, update_calibration
    from ..detection.grid import size_text
    from ..files import check_outputs

    if args.update is not None:
        if args.symbol or args.cell_size is not None or args.workspace:
            raise InputError("--update: --symbol, --cell-size and --workspace belong to a new calibration; "
                             "an update keeps the calibration's own")
        # the updated file may replace the calibration it updates (the default), never the frame
        check_outputs({"-o": args.output or args.update}, {"frame": args.reference})
        old = load_calibration(args.update)
        cal, motion = update_calibration(old, args.reference, **stage_choices(args))
        output = args.output or args.update
        cal.save(output)
        print(f"re-anchored to the {motion.summary()}")
        print(f"wrote {output}")
        return 0
    if not args.output:
        raise InputError("-o/--output: the calibration file to write is required")
    check_outputs({"-o": args.output}, {"reference": args.reference, "--symbol": args.symbol,
                                        "--workspace": args.workspace})
    workspace = args.workspace
    if workspace is None and args.cell_size is None:
        beside = Path(args.reference).parent / "workspace.toml"
        workspace = beside if beside.is_file() else None
    cal = calibrate(args.reference, symbol=args.symbol, workspace=workspace, cell_size=args.cell_size,
                    **stage_choices(args))
    cal.save(args.output)
    g = cal.grid
    dx, dy = g.pitch_px
    print(f"grid {size_text(g.cols, g.rows)} ({cal.symbols_expected} symbols), pitch {dx:.1f} x {dy:.1f} px, "
          f"tolerance {g.tolerance_px:.1f} px")
    print(f"match threshold {cal.threshold:.4f} ({cal.stages['matcher']['name']}), margin {cal.margin:.1f}x "
          f"(nearest other contour / farthest symbol)")
    print(f"wrote {args.output}")
    return 0
