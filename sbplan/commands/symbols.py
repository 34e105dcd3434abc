"""``sbplan symbols``: rank candidate reference symbols, print floor tiles, draw a symbol."""

from __future__ import annotations

import argparse
import json
import sys

#: ``sbplan symbols`` alone prints the list of actions.
BARE_HELP = True
HELP = "choose the reference symbol (rank candidates), print floor tiles, show a symbol"
DESCRIPTION = ("Paper section 3: rank candidate symbols by equations (2)-(4), regularity and confusion "
               "margin (rank); write a printable tile (render); draw a symbol in the terminal (show).")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="symbols_command", metavar="ACTION", required=True)

    p = sub.add_parser("rank", help="rank the candidate symbols and recommend one",
                       description="Render each candidate as the camera sees it, compute its descriptors, "
                                   "the paper's equations (2)-(4), a regularity score and a confusion margin "
                                   "against noise contours; print the ranked table and the recommended symbol.")
    p.add_argument("names", nargs="*", metavar="NAME", help="candidates to rank (default: every registered symbol)")
    p.add_argument("--matcher", default="fourier", metavar="NAME", help="descriptor matcher (default: fourier)")
    p.add_argument("--binarizer", default="otsu", metavar="NAME", help="binarizer for the rendered views (default: otsu)")
    p.add_argument("--extractor", default="opencv", metavar="NAME", help="contour extractor (default: opencv)")
    p.add_argument("--approximator", default="douglas-peucker", metavar="NAME",
                   help="polygon approximator (default: douglas-peucker)")
    p.add_argument("--noise-set", default="all", metavar="FAMILIES",
                   help="comma-separated noise families: blobs, circles, ellipses, occluded, edges (default: all)")
    p.add_argument("--noise-count", type=int, default=12, metavar="N", help="noise shapes per family (default: 12)")
    p.add_argument("--min-regularity", type=float, default=0.5, metavar="SHARE",
                   help="condition 3: least share of straight outline (default: 0.5)")
    p.add_argument("--min-margin", type=float, default=2.0, metavar="X",
                   help="least confusion margin of the recommended symbol (default: 2.0)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise set (default: 0)")
    p.add_argument("--plot", metavar="DIR", help="write the figures (FD amplitudes, mean/variance, distance "
                                                 "heat map, margins) as PNG files into DIR")
    p.add_argument("--json", action="store_true", help="print the ranking as JSON instead of the table")
    p.add_argument("-o", "--output", metavar="FILE", help="also write the ranking as JSON to FILE (atomically)")
    p.set_defaults(_symbols=_rank)

    p = sub.add_parser("render", help="write a printable floor tile (SVG, PDF or PNG)",
                       description="A square tile of the grid pitch with the symbol's centre of area at its "
                                   "centre, crop marks and a label; lay tiles edge to edge to cover a floor.")
    p.add_argument("name", help="symbol name (see 'sbplan symbols rank' or 'sbplan plugins')")
    p.add_argument("--size", default="200mm", help="tile side = grid pitch, e.g. 200mm, 25cm, 8in (default: 200mm)")
    p.add_argument("--symbol-fraction", type=float, default=0.45, metavar="F",
                   help="symbol box as a fraction of the tile (default: 0.45, as the renderer)")
    p.add_argument("--symbol-size", metavar="LENGTH", help="symbol box side as a length (overrides --symbol-fraction)")
    p.add_argument("--angle", type=float, default=0.0, help="rotation in degrees, counter-clockwise (default: 0)")
    p.add_argument("--dpi", type=float, default=300.0, help="resolution of a PNG tile (default: 300)")
    p.add_argument("--no-crop-marks", action="store_true", help="no margin, marks or label: the page is the tile")
    p.add_argument("--format", choices=("svg", "pdf", "png"), help="output format (default: from the suffix)")
    p.add_argument("-o", "--output", required=True, help="file to write: .svg, .pdf or .png")
    p.set_defaults(_symbols=_render)

    p = sub.add_parser("show", help="draw a symbol in the terminal")
    p.add_argument("name", help="symbol name")
    p.add_argument("--width", type=int, default=32, help="width in terminal columns (default: 32)")
    p.add_argument("--mode", choices=("half", "braille"), default="half",
                   help="half-blocks (default) or braille dots")
    p.add_argument("--angle", type=float, default=0.0, help="rotation in degrees, counter-clockwise")
    p.add_argument("--invert", action="store_true", help="draw the floor instead of the ink")
    p.set_defaults(_symbols=_show)

    p = sub.add_parser("list", help="list the registered candidate symbols")
    p.set_defaults(_symbols=_list)


def run(args: argparse.Namespace) -> int:
    return args._symbols(args)


def _rank(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and rich
    from ..imageio import write_json
    from ..symbols.rank import rank_symbols

    from ._progress import StderrProgress

    # shown once ranking has taken a second: quick runs stay quiet
    progress = StderrProgress("ranking symbols", delay=1.0)
    try:
        ranking = rank_symbols(args.names or None, matcher=args.matcher, binarizer=args.binarizer,
                               extractor=args.extractor, approximator=args.approximator,
                               noise_families=args.noise_set, noise_per_family=args.noise_count,
                               min_regularity=args.min_regularity, min_margin=args.min_margin, seed=args.seed,
                               progress=progress)
    finally:
        progress.close()
    data = ranking.to_dict()
    if args.output:
        write_json(args.output, data)
    figures = []
    if args.plot:
        from ..symbols.plots import write_figures

        figures = write_figures(ranking, args.plot)
    if args.json:
        json.dump(data, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    print(ranking.table())
    print(f"\n{len(ranking.names)} candidates, {ranking.seconds:.1f} s; matcher {args.matcher}; "
          "* recommended, x fails regularity or margin")
    if ranking.recommended:
        i = ranking.names.index(ranking.recommended)
        print(f"recommended symbol: {ranking.recommended} (eq. 4 score {ranking.score[i]:.4f}, regularity "
              f"{ranking.regularity[i]:.2f}, confusion margin {ranking.margin[i]:.2f})")
    else:
        print(f"no candidate has regularity >= {args.min_regularity:g} and margin >= {args.min_margin:g}; "
              "lower --min-margin or add candidates")
    for f in figures:
        print(f"wrote {f}")
    if args.output:
        print(f"wrote {args.output}")
    return 0


def _render(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and rich
    from ..symbols.tile import write_tile

    tile = write_tile(args.output, args.name, fmt=args.format, dpi=args.dpi, size=args.size,
                      symbol_fraction=args.symbol_fraction, symbol_size=args.symbol_size, angle=args.angle,
                      crop_marks=not args.no_crop_marks)
    extra = f" at {args.dpi:g} dpi" if (args.format or args.output.lower().rsplit(".", 1)[-1]) == "png" else ""
    print(f"wrote {args.output}: {tile.name}, tile {tile.size:g} mm (page {tile.page:g} mm), "
          f"symbol {tile.symbol_size:.4g} mm{extra}")
    return 0


def _show(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and rich
    from ..symbols.terminal import draw

    print(draw(args.name, width=args.width, mode=args.mode, angle=args.angle, invert=args.invert))
    return 0


def _list(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and rich
    from .. import registry

    for name, info in registry.registry().symbols().items():
        print(f"{name:<20} {info.description}")
    return 0
