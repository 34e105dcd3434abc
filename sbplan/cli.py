"""The ``sbplan`` command.

Each subcommand lives in its own module under :mod:`sbplan.commands` with ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``. Command modules import heavy libraries inside
``run`` so that ``sbplan --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import traceback

from .errors import EXIT_CODES, SbplanError

#: Subcommand name -> module, in the order ``sbplan --help`` lists them.
COMMANDS = {
    "demo": "sbplan.commands.demo",
    "calibrate": "sbplan.commands.calibrate",
    "detect": "sbplan.commands.detect",
    "plan": "sbplan.commands.plan",
    "watch": "sbplan.commands.watch",
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
        epilog="exit codes:\n" + "\n".join(f"  {k:>3}  {v}" for k, v in EXIT_CODES.items()),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show tracebacks and library log lines (OMPL) on errors (also after the command)")
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
    _verbose_everywhere(sub)
    return parser


def _verbose_everywhere(sub: argparse._SubParsersAction) -> None:
    """``-v`` after the command (and after a subcommand's action) as well as before it. SUPPRESS:
    not given there, it leaves the top-level value alone."""
    for p in set(sub.choices.values()):
        if not any("-v" in a.option_strings for a in p._actions):
            p.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                           help="show tracebacks and library log lines on errors")
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                _verbose_everywhere(a)


#: An option's value that starts with a minus and holds a comma (``--start -5,-5``): argparse
#: takes it for an option unless it is joined to its option with ``=``.
_NEGATIVE_PAIR = re.compile(r"^-\.?\d[^,]*,")


def _join_negative_pairs(argv: list[str]) -> list[str]:
    out: list[str] = []
    for a in argv:
        if out and _NEGATIVE_PAIR.match(a) and out[-1].startswith("--") and "=" not in out[-1]:
            out[-1] = f"{out[-1]}={a}"
        else:
            out.append(a)
    return out


def main(argv: list[str] | None = None) -> int:
    argv = _join_negative_pairs(sys.argv[1:] if argv is None else list(argv))
    selected = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(selected if selected in COMMANDS else None)
    if selected in COMMANDS and argv[-1] == selected:
        # a command group named alone (sbplan bench, synth, symbols) shows its help, not an error
        module = import_command(COMMANDS[selected])
        if getattr(module, "BARE_HELP", False):
            argv = [*argv, "--help"]
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    if args.verbose:
        import logging

        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("sbplan: %(levelname)s: %(message)s"))
        logging.getLogger("sbplan").addHandler(handler)
        logging.getLogger("sbplan").setLevel(logging.INFO)
    try:
        return int(args._run(args) or 0)
    except SbplanError as exc:
        if args.verbose:
            traceback.print_exc()
        print(f"sbplan: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("sbplan: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
