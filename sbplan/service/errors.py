"""What the service answers when a request cannot be served, and how sbplan's errors map to HTTP.

Every error response is JSON ``{"code": ..., "message": ...}`` (:class:`sbplan.service.models.Error`):
``code`` a short stable tag a program can switch on, ``message`` one readable line. Bad input is a
4xx; a 500 means a bug, and its body never carries a traceback (the server's log does).
"""

from __future__ import annotations

from ..errors import (CameraMotionError, DetectionError, ImageError, InputError, LimitError, NoFloorError,
                      PlanningError, SbplanError, StageError)


class ServiceError(SbplanError):
    """A request the service refuses; ``status`` is the HTTP status, ``code`` the error's tag."""

    status: int = 400
    code: str = "bad-request"

    def __init__(self, message: str, *, code: str | None = None, status: int | None = None):
        super().__init__(message)
        if code is not None:
            self.code = code
        if status is not None:
            self.status = status


class NoFrameError(ServiceError):
    """No frame has been detected yet, so there are no obstacles to answer from."""

    status, code = 409, "no-frame"


class UnknownRouteError(ServiceError):
    status, code = 404, "unknown-route"


class PayloadTooLargeError(ServiceError):
    status, code = 413, "too-large"


class UnsupportedMediaError(ServiceError):
    status, code = 415, "unsupported-media-type"


class BusyError(ServiceError):
    """Too many frames are waiting for detection."""

    status, code = 503, "busy"


def status_and_code(exc: SbplanError) -> tuple[int, str]:
    """The HTTP status and error code of one of sbplan's errors.

    Planning errors carry their own tag (``start-in-obstacle``, ``no-route``, ...); a camera that
    moved beyond what registration compensates is a conflict with the calibration (409), not bad
    input: the client cannot fix it by sending the frame again.
    """
    if isinstance(exc, ServiceError):
        return exc.status, exc.code
    if isinstance(exc, PlanningError):
        return 422, exc.reason
    if isinstance(exc, NoFloorError):  # a dead camera or a dark room: a better frame fixes it
        return 422, "no-floor"
    if isinstance(exc, CameraMotionError):
        return 409, "camera-moved"
    if isinstance(exc, StageError):  # the server's plugin failed, not the client's input
        return 500, "stage-failed"
    if isinstance(exc, LimitError):
        return 413, "limit-exceeded"
    if isinstance(exc, ImageError):
        return 415, "not-an-image"
    if isinstance(exc, DetectionError):
        return 422, "detection-failed"
    if isinstance(exc, InputError):
        return 422, "invalid-input"
    return 422, "rejected"
