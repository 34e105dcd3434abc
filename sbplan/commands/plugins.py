"""``sbplan plugins``: every installed stage with its kind, name, origin and description."""

from __future__ import annotations

import argparse
import json

from ..errors import PluginError

HELP = "list the installed stages (kind, name, origin, description) and plugins that failed"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--options", action="store_true", help="also list each stage's options")


def run(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and the pipeline
    from .. import registry

    infos = registry.stages()
    failures = registry.load_errors()  # listed below
    if args.json:
        print(json.dumps({
            "stages": [{"kind": s.kind, "name": s.name, "origin": s.origin, "description": s.description,
                        "options": [{"name": o.name, "type": o.type.__name__, "default": o.default, "help": o.help}
                                    for o in s.cls.options()]} for s in infos],
            "symbols": registry.symbol_names(),
            "failures": [{"plugin": f.plugin, "origin": f.origin, "error": f.error} for f in failures],
        }, indent=2, default=str))
        return PluginError.exit_code if failures else 0
    rows = [("KIND", "NAME", "ORIGIN", "DESCRIPTION")] + [(s.kind, s.name, s.origin, s.description) for s in infos]
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    for r in rows:
        print(f"{r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]:<{widths[2]}}  {r[3]}")
        if args.options and r[0] != "KIND":
            cls = next(s.cls for s in infos if (s.kind, s.name) == (r[0], r[1]))
            for o in cls.options():
                print(f"{'':<{widths[0]}}    --option {o.name}={o.default!r}  ({o.type.__name__}) {o.help}")
    symbols = registry.symbol_names()
    if symbols:
        print(f"\n{len(symbols)} candidate symbols: {', '.join(symbols)}")
    for f in failures:
        print(f"\nplugin {f.plugin!r} from {f.origin} failed to load: {f.error}")
    return PluginError.exit_code if failures else 0
