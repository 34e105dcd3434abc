"""The ``sbplan`` command.

Each subcommand lives in its own module under :mod:`sbplan.commands` with ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``. Command modules import heavy libraries inside
``run`` so that ``sbplan --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import re
import sys

from . import __version__
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
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    _log_options(parser, None)
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


def _log_options(parser: argparse.ArgumentParser, default: object) -> None:
    """-v, -q and --log-json: how much of the log (sbplan.logs) shows on stderr, and in which form.
    ``default`` None: the top level's defaults; SUPPRESS: a command's copy leaves them alone (and
    an option string the command uses itself, such as a ``-q`` of its own, is left to it)."""
    taken = {s for a in parser._actions for s in a.option_strings}

    def add(flags: tuple[str, ...], **kw: object) -> None:
        free = [f for f in flags if f not in taken]
        if free:
            parser.add_argument(*free, **kw)  # type: ignore[arg-type]

    add(("-v", "--verbose"), action="count", default=0 if default is None else default,
        help="more log lines on stderr: -v what was done (and OMPL's log, plugins that failed to load, "
             "tracebacks on errors), -vv stages and timings (also after the command)")
    add(("-q", "--quiet"), action="store_true", default=False if default is None else default,
        help="errors only on stderr (no warnings)")
    add(("--log-json",), action="store_true", default=False if default is None else default,
        help="log lines (warnings, errors, -v's) as one JSON object each, for machines")


def _verbose_everywhere(sub: argparse._SubParsersAction) -> None:
    """-v, -q and --log-json after the command (and after a subcommand's action) as well as before
    it. SUPPRESS: not given there, they leave the top-level values alone."""
    for p in set(sub.choices.values()):
        _log_options(p, argparse.SUPPRESS)
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
