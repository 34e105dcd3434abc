"""What every job screen shares: long steps in a worker, with progress, cancel and one error path."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from textual import work
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Input
from textual.worker import Worker, get_current_worker

from ...errors import Cancelled
from ..session import display_path
from ..widgets.busy import Busy
from .confirm import ConfirmScreen

if TYPE_CHECKING:
    from textual import getters

    from ..app import SbplanApp
    from ..session import Session

#: ``progress(stage, fraction)``: what a step's function is given to report where it is
Progress = Callable[[str, "float | None"], None]


class JobScreen(Screen):
    """A screen whose long steps (open, calibrate, detect, plan, export) run in a thread worker.

    One step at a time per screen (``exclusive``): starting another cancels the previous one.
    A step's function receives ``progress(stage, fraction)``; each call shows the stage and the
    share done above the footer, and raises :class:`~sbplan.errors.Cancelled` once Cancel was
    asked, so the step stops at its next stage (the library's long calls, such as calibration,
    take the same callback). Errors are shown once, here, for every step.
    """

    BINDINGS = [Binding("escape", "cancel", "Cancel", show=False)]
    #: Input id -> file name under the session's output folder ("": the folder itself): fields
    #: that follow the map, so that another map's outputs never go over this one's.
    OUTPUT_FIELDS: dict[str, str] = {}

    if TYPE_CHECKING:  # the app these screens run in (Textual's own pattern; it types it as any App)
        app = getters.app(SbplanApp)

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._threads: set[int] = set()  # tokens of steps whose thread has not returned yet
        self._lock = threading.Lock()
        self._out_seen: Path | None = None

    def output_default(self, field: str) -> str:
        name = self.OUTPUT_FIELDS[field]
        return str(self.session.out_dir / name) if name else str(self.session.out_dir)

    def follow_map(self) -> None:
        """Point the output fields at the current map's output folder when the map changed."""
        out = self.session.out_dir
        if out == self._out_seen:
            return
        self._out_seen = out
        for field in self.OUTPUT_FIELDS:
            self.query_one(f"#{field}", Input).value = self.output_default(field)

    def confirm_overwrite(self, paths: list, then: Callable[[], None], *, question: str | None = None) -> None:
        """Run ``then()`` at once when none of ``paths`` exists and no ``question`` is given;
        otherwise only after the operator said yes."""
        existing = [p for p in paths if Path(p).exists()]
        if not existing and question is None:
            then()
            return
        if question is None:
            question = "Overwrite " + ", ".join(display_path(p) for p in existing) + "?"

        def answered(yes: bool | None) -> None:
            if yes:
                then()
            else:
                self.notify("nothing was written", title="cancelled")

        self.app.push_screen(ConfirmScreen(question), answered)

    @property
    def session(self) -> Session:
        return self.app.session

    @property
    def running(self) -> bool:
        """A step's thread is still running (also while it winds down after Cancel)."""
        with self._lock:
            return bool(self._threads)

    def start_job(self, label: str, fn: Callable[[Progress], Any], done: Callable[[Any], None], *,
                  failed: Callable[[Exception], None] | None = None) -> None:
        """Run ``fn(progress)`` in a worker; then ``done(result)`` on the UI thread. An error is
        reported to the operator, after ``failed(error)`` (when given) updated the screen."""
        token = self.query_one(Busy).start(label)
        with self._lock:
            self._threads.add(token)
        self._job(token, label, fn, done, failed)

    @work(thread=True, exclusive=True, group="job", exit_on_error=False)
    def _job(self, token: int, label: str, fn: Callable[[Progress], Any], done: Callable[[Any], None],
             failed: Callable[[Exception], None] | None) -> None:
        worker = get_current_worker()

        def progress(stage: str, fraction: float | None = None) -> None:
            self._progress(worker, token, label, stage, fraction)

        try:
            try:
                result = fn(progress)
            except Cancelled:
                self._to_ui(self._job_cancelled, token, label)
                return
            except Exception as exc:  # noqa: BLE001  (shown to the operator; the app stays usable)
                if worker.is_cancelled:
                    self._to_ui(self._job_cancelled, token, label)
                else:
                    self._to_ui(self._job_failed, token, exc, failed)
                return
            if worker.is_cancelled:
                self._to_ui(self._job_cancelled, token, label)
            else:
                self._to_ui(self._job_done, token, done, result)
        finally:
            with self._lock:
                self._threads.discard(token)

    def _progress(self, worker: Worker, token: int, label: str, stage: str, fraction: float | None) -> None:
        """In the worker thread: stop here if Cancel was asked, else show the stage."""
        if worker.is_cancelled:
            raise Cancelled(f"{label}: cancelled at {stage}")
        self._to_ui(self.query_one(Busy).progress, token, stage, fraction)

    def _to_ui(self, fn: Callable, *args) -> None:
        try:
            self.app.call_from_thread(fn, *args)
        except RuntimeError:  # the app is closing: nobody is left to show it to
            pass

    def _job_done(self, token: int, done: Callable[[Any], None], result: Any) -> None:
        self.query_one(Busy).stop(token)
        try:
            done(result)
        except Exception as exc:  # noqa: BLE001
            self.app.report_error(exc)

    def _job_failed(self, token: int, exc: Exception, failed: Callable[[Exception], None] | None) -> None:
        self.query_one(Busy).stop(token)
        if failed is not None:
            try:
                failed(exc)
            except Exception as inner:  # noqa: BLE001
                self.app.report_error(inner)
        self.app.report_error(exc)

    def _job_cancelled(self, token: int, label: str) -> None:
        # a step replaced by a newer one ends quietly; the one the operator cancelled says so
        if self.query_one(Busy).stop(token):
            self.notify(f"{label}: cancelled", title="cancel")

    @property
    def busy(self) -> bool:
        return any(w.group == "job" and not w.is_finished for w in self.workers if w.node is self)

    def action_cancel(self) -> None:
        if self.busy:
            self.workers.cancel_node(self)
            self.query_one(Busy).cancelling()

    def on_busy_cancel_requested(self, event: Busy.CancelRequested) -> None:
        self.action_cancel()

    def session_changed(self) -> None:
        """Another screen's step changed the session (a calibration finished) while this one is
        shown: catch up as when this screen is switched to."""
        resume = getattr(self, "on_screen_resume", None)
        if resume is not None:
            resume()

    def show_fullscreen(self, image, labels=(), title: str = "") -> None:
        from .picture import PictureScreen

        if image is None:
            self.notify("no picture yet", title="full screen")
            return
        self.app.push_screen(PictureScreen(image, labels, title))
