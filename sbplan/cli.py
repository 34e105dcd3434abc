"""The ``sbplan`` command.

Each subcommand lives in its own module under :mod:`sbplan.commands` with ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``. Command modules import heavy libraries inside
``run`` so that ``sbplan --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from . import __version__
from .errors import SbplanError

#: Subcommand name -> module, in the order ``sbplan --help`` lists them.
COMMANDS = {
    "demo": "sbplan.commands.demo",
    "calibrate": "sbplan.commands.calibrate",
    "detect": "sbplan.commands.detect",
    "plan": "sbplan.commands.plan",
    "synth": "sbplan.commands.synth",
    "symbols": "sbplan.commands.symbols",
    "tui": "sbplan.commands.tui",
    "serve": "sbplan.commands.serve",
    "plugins": "sbplan.commands.plugins",
    "bench": "sbplan.commands.bench",
}


def import_command(module_name: str):
    """The command module, or None when that module itself is not part of this installation."""
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name == module_name:
            return None
        raise


def build_parser(selected: str | None = None) -> argparse.ArgumentParser:
    """The argument parser. ``selected`` names the command about to run: the others may register
    a light parser (``add_arguments_light``) so that start-up does not import what they need."""
    parser = argparse.ArgumentParser(
        prog="sbplan",
        description="Find obstacles on a floor of reference symbols from a ceiling camera, and plan routes around them.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log lines on stderr: -v what was done (and OMPL's log, tracebacks on "
                             "errors), -vv stages and timings")
    parser.add_argument("-q", "--quiet", action="store_true", help="errors only on stderr (no warnings)")
    parser.add_argument("--log-json", action="store_true",
                        help="log lines (warnings, errors, -v's) as one JSON object each, for machines")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module_name in COMMANDS.items():
        module = import_command(module_name)
        if module is None:
            continue
        p = sub.add_parser(name, help=module.HELP, description=getattr(module, "DESCRIPTION", module.HELP))
        light = getattr(module, "add_arguments_light", None)
        if light is not None and name != selected:
            light(p)
        else:
            module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    selected = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(selected if selected in COMMANDS else None)
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    from .logs import configure

    undo = configure(verbosity=args.verbose, quiet=args.quiet, json_lines=args.log_json)
    try:
        return int(args._run(args) or 0)
    except SbplanError as exc:
        logging.getLogger("sbplan.cli").error(str(exc), exc_info=exc if args.verbose else None)
        return exc.exit_code
    except KeyboardInterrupt:
        print("sbplan: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
    finally:
        undo()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
