"""The one exception tree of sbplan.

Every error a user can cause derives from :class:`SbplanError`. The CLI prints ``str(error)`` as
one line and exits with ``error.exit_code``; anything else is a bug and gets a traceback.
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


class ContourError(InputError):
    """A contour or polygon is degenerate (too few points, wrong shape, not finite)."""


class PluginError(SbplanError):
    """A plugin or stage could not be found, loaded or used."""


class UnknownStageError(PluginError, LookupError):
    """No stage of that kind is registered under that name."""

    def __init__(self, kind: str, name: str, installed: list[str]):
        self.kind, self.name, self.installed = kind, name, list(installed)
        listing = ", ".join(self.installed) if self.installed else "none"
        super().__init__(f"unknown {kind} {name!r}; installed: {listing}")


class SceneError(InputError):
    """Scene-rendering options that cannot produce a valid floor."""


class CalibrationError(SbplanError):
    """A reference image cannot be calibrated, or a calibration file is unusable."""


class DetectionError(SbplanError):
    """A scene cannot be processed with the given calibration."""


class CameraMotionError(DetectionError):
    """The camera's movement since calibration cannot be estimated or is too large to compensate:
    recalibrate (or re-anchor the calibration with ``sbplan calibrate --update``)."""

class MapFormatError(InputError):
    """An obstacle file, map folder or occupancy map is missing or malformed."""


class PlanningError(SbplanError):
    """A route cannot be planned; ``reason`` is a short machine-readable tag."""

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

    exit_code = 130
