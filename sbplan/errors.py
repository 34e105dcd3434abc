"""The one exception tree of sbplan, and the command's exit codes.

Every error a user can cause derives from :class:`SbplanError`. The CLI prints ``str(error)`` as
one line and exits with ``error.exit_code``; anything else is a bug and gets a traceback (exit 1).

Exit codes (one scheme for every command; docs/operator-guide.md lists them):

====  ==========================================================================================
0     success
1     an internal error (a bug): the traceback is printed (an SbplanError of no family below also
      exits 1; sbplan raises none)
2     the command line: an unknown option, a value sbplan cannot use (:class:`InputError`)
3     an input file is missing, unreadable or malformed: image, calibration, obstacle file,
      workspace (:class:`ImageError`, :class:`MapFormatError`, :class:`CalibrationFileError`)
4     an output cannot be written (:class:`OutputError`)
5     calibration failed: the reference image shows no usable symbol grid (:class:`CalibrationError`)
6     detection refused: the frame does not fit the calibration (camera moved, no floor in view,
      another floor's calibration) (:class:`DetectionError`)
7     no route: start or goal in an obstacle or out of bounds, or no route exists (:class:`PlanningError`)
8     a plugin stage is missing, failed to load or failed at run time (:class:`PluginError`)
9     a size, memory or time limit was exceeded (:class:`LimitError`)
130   interrupted (Ctrl-C)
====  ==========================================================================================
"""

from __future__ import annotations


class SbplanError(Exception):
    """Root of every error sbplan raises on purpose."""

    exit_code: int = 1


class InputError(SbplanError, ValueError):
    """A parameter, option or argument has a value sbplan cannot use."""

    exit_code = 2


class ImageError(InputError):
    """An image cannot be read, or is not an image sbplan can process."""

    exit_code = 3


class ContourError(InputError):
    """A contour or polygon is degenerate (too few points, wrong shape, not finite)."""


class OutputError(SbplanError, OSError):
    """An output file or folder cannot be written (or must not be: a device, a link, an input)."""

    exit_code = 4


class PluginError(SbplanError):
    """A plugin or stage could not be found, loaded or used."""

    exit_code = 8


class UnknownStageError(PluginError, LookupError):
    """No stage of that kind is registered under that name."""

    def __init__(self, kind: str, name: str, installed: list[str], failed: list[str] | None = None):
        self.kind, self.name, self.installed = kind, name, list(installed)
        listing = ", ".join(self.installed) if self.installed else "none"
        note = ""
        if failed:
            note = f"; plugins that failed to load (see 'sbplan plugins'): {', '.join(failed)}"
        super().__init__(f"unknown {kind} {name!r}; installed: {listing}{note}")


class StageError(PluginError):
    """A stage (a plugin's or a built-in one) failed at run time or broke its contract: raised,
    or returned something of the wrong type, shape or value. The message names the stage's kind,
    its name, where it comes from and what was wrong."""

    def __init__(self, kind: str, name: str, origin: str, what: str):
        self.kind, self.name, self.origin, self.what = kind, name, origin, what
        source = f" (from {origin})" if origin else ""
        super().__init__(f"{kind} {name!r}{source} {what}")


class SceneError(InputError):
    """Scene-rendering options that cannot produce a valid floor."""


class CalibrationError(SbplanError):
    """A reference image cannot be calibrated, or a calibration file is unusable."""

    exit_code = 5


class CalibrationFileError(CalibrationError):
    """A calibration file is missing, not a calibration, or holds a value detection cannot use."""

    exit_code = 3


class DetectionError(SbplanError):
    """A scene cannot be processed with the given calibration."""

    exit_code = 6


class CameraMotionError(DetectionError):
    """The camera's movement since calibration cannot be estimated or is too large to compensate:
    recalibrate (or re-anchor the calibration with ``sbplan calibrate --update``)."""


class NoFloorError(CameraMotionError):
    """The frame shows no floor at all (uniform, very dark, noise): a dead or covered camera, not a
    moved one. A :class:`CameraMotionError` for callers that treat every unusable view alike."""


class MapFormatError(InputError):
    """An obstacle file, map folder or occupancy map is missing or malformed."""

    exit_code = 3


class LimitError(SbplanError):
    """A size, memory or time limit would be exceeded (see :mod:`sbplan.limits` for the limits and
    how to raise them)."""

    exit_code = 9


class PlanningError(SbplanError):
    """A route cannot be planned; ``reason`` is a short machine-readable tag."""

    exit_code = 7
    reason: str = "planning-failed"


class StartInObstacleError(PlanningError):
    reason = "start-in-obstacle"


class GoalInObstacleError(PlanningError):
    reason = "goal-in-obstacle"


class OutOfBoundsError(PlanningError, InputError):
    reason = "out-of-bounds"


class NoRouteError(PlanningError):
    reason = "no-route"


class Cancelled(SbplanError):
    """A long step was stopped on request: a ``progress`` callback raised it between two steps
    (the terminal app's Cancel), and the step's result was never made."""

    exit_code = 130  # as an interrupted command


#: exit code -> what it means, for ``sbplan --help`` and the docs
EXIT_CODES = {
    0: "success",
    1: "internal error (a bug; the traceback is printed)",
    2: "bad command line: unknown option or unusable value",
    3: "an input file is missing, unreadable or malformed",
    4: "an output cannot be written",
    5: "calibration failed: no usable symbol grid in the reference",
    6: "detection refused: the frame does not fit the calibration",
    7: "no route (start/goal blocked or out of bounds, or none exists)",
    8: "a plugin stage is missing, failed to load or failed",
    9: "a size, memory or time limit was exceeded",
    130: "interrupted",
}
