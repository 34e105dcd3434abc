"""``sbplan bench``: the benchmarks. Speed is measured here, never in tests."""

from __future__ import annotations

import argparse
from ..cli import import_command

HELP = "run a benchmark (match, stages, ...) and print its table"
#: ``sbplan bench`` alone prints the list of benchmarks.
BARE_HELP = True

#: Benchmark name -> module under sbplan.bench.
BENCHMARKS: dict[str, str] = {
    "stages": "sbplan.bench.stage_timings",
    "match": "sbplan.bench.match",
    "detect": "sbplan.bench.detect",
    "plan": "sbplan.bench.plan",
    "serve": "sbplan.bench.serve",
    "watch": "sbplan.bench.watch",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="benchmark", metavar="BENCHMARK", required=True)
    for name, module_name in BENCHMARKS.items():
        module = import_command(module_name)
        if module is None:
            continue
        p = sub.add_parser(name, help=module.HELP, description=getattr(module, "DESCRIPTION", module.HELP))
        module.add_arguments(p)
        p.set_defaults(_bench=module.run)


def add_arguments_light(parser: argparse.ArgumentParser) -> None:
    """Nothing: benchmark modules import numpy and OpenCV, which other commands need not wait for."""


def run(args: argparse.Namespace) -> int:
    return args._bench(args)
