"""sbplan's log: the library logs, the command line shows.

Every module logs to a child of the ``sbplan`` logger (``logging.getLogger(__name__)``): the
stages chosen and the timings at DEBUG, what was calibrated or planned at INFO, and what a user
should know about (a camera that moved, an assumed pose) at WARNING. The library never prints and
never configures logging; ``sbplan/__init__.py`` gives the ``sbplan`` logger a ``NullHandler`` so
that a program which configures nothing sees nothing (not Python's last-resort stderr output).

A program using sbplan shows its log as any other library's::

    import logging
    logging.basicConfig(level=logging.INFO)   # or logging.getLogger("sbplan").setLevel(...)

The ``sbplan`` command calls :func:`configure`: warnings and errors by default (but not the
registry's warnings about plugins that failed to load), ``-v`` adds INFO and those, ``-vv``
DEBUG, ``-q`` errors only, ``--log-json`` one JSON object per record (for machines).
A record's structured fields are passed as ``extra={"data": {...}}``; the JSON form carries them
as ``data``.
"""

from __future__ import annotations

import datetime
import json
import logging
import sys
from typing import Any, Callable, TextIO

LOGGER = "sbplan"

__all__ = ["LOGGER", "configure", "JsonFormatter", "TextFormatter"]


class TextFormatter(logging.Formatter):
    """``sbplan: warning: message``, the form of the command's error lines; the logger's name is
    added below WARNING (where many modules speak)."""

    def format(self, record: logging.LogRecord) -> str:
        level = record.levelname.lower()
        text = record.getMessage()
        if record.levelno < logging.WARNING:
            text = f"[{record.name}] {text}"
        line = f"sbplan: {level}: {text}"
        if record.exc_info:
            line += "\n" + self.formatException(record.exc_info)
        return line


class JsonFormatter(logging.Formatter):
    """One JSON object per record: ``time`` (ISO 8601, UTC), ``level``, ``logger``, ``message``
    and, when the record has them, ``data`` (its structured fields) and ``exception``."""

    def format(self, record: logging.LogRecord) -> str:
        out: dict[str, Any] = {
            "time": datetime.datetime.fromtimestamp(record.created, datetime.timezone.utc).isoformat(
                timespec="milliseconds"),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        data = getattr(record, "data", None)
        if data is not None:
            out["data"] = data
        if record.exc_info:
            out["exception"] = self.formatException(record.exc_info)
        return json.dumps(out, default=_jsonable)


def _jsonable(obj: Any) -> Any:
    from .imageio import json_default

    try:
        return json_default(obj)
    except TypeError:
        return repr(obj)


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is when a record comes: the TUI (Textual captures
    stderr while it runs) and pytest's capture get the lines, not the terminal under them."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    @property  # type: ignore[override]
    def stream(self) -> TextIO:
        return sys.stderr

    @stream.setter
    def stream(self, value: TextIO) -> None:
        pass


def _plugin_failures_only_when_asked(record: logging.LogRecord) -> bool:
    """A plugin that failed to load is the registry's warning for those who ask (``-v``,
    ``sbplan plugins``, a stage of it named): a command that does not need it says nothing."""
    return not (record.name == "sbplan.registry" and record.levelno < logging.ERROR)


def configure(*, verbosity: int = 0, quiet: bool = False, json_lines: bool = False,
              stream: TextIO | None = None) -> Callable[[], None]:
    """Show the ``sbplan`` log on ``stream`` (default stderr), as the command line does.

    Parameters
    ----------
    verbosity : int
        0: warnings and errors; 1: and INFO; 2 or more: and DEBUG.
    quiet : bool
        Errors only (overrides ``verbosity``).
    json_lines : bool
        One JSON object per line (:class:`JsonFormatter`) instead of text.
    stream : file, optional

    Returns
    -------
    callable
        Undoes the configuration (the handler, the level, propagation), so that a program or a
        test that runs the command in-process gets its logging back as it was.
    """
    logger = logging.getLogger(LOGGER)
    level = (logging.ERROR if quiet else logging.WARNING if verbosity <= 0
             else logging.INFO if verbosity == 1 else logging.DEBUG)
    handler = logging.StreamHandler(stream) if stream is not None else _StderrHandler()
    handler.setFormatter(JsonFormatter() if json_lines else TextFormatter())
    if verbosity <= 0:
        handler.addFilter(_plugin_failures_only_when_asked)
    before = (logger.level, logger.propagate)
    logger.addHandler(handler)
    logger.setLevel(level)
    # The command's handler shows every record once, whatever the root logger does.
    logger.propagate = False

    def undo() -> None:
        logger.removeHandler(handler)
        logger.setLevel(before[0])
        logger.propagate = before[1]

    return undo
