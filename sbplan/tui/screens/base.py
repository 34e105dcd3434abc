"""What every job screen shares: running a long step in a worker, with progress and cancel."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

from textual import work
from textual.binding import Binding
from textual.screen import Screen
from textual.worker import get_current_worker

from ..widgets.busy import Busy

if TYPE_CHECKING:
    from textual import getters

    from ..app import SbplanApp
    from ..session import Session


class JobScreen(Screen):
    """A screen whose long steps (calibrate, detect, plan) run in a thread worker.

    One step at a time per screen (``exclusive``): starting another cancels the previous one.
    A thread cannot be interrupted inside a library call, so Cancel hides the progress line at
    once and discards the result when the call returns.
    """

    BINDINGS = [Binding("escape", "cancel", "Cancel", show=False)]

    if TYPE_CHECKING:  # the app these screens run in (Textual's own pattern; it types it as any App)
        app = getters.app(SbplanApp)

    @property
    def session(self) -> Session:
        return self.app.session

    def start_job(self, label: str, fn: Callable[[], Any], done: Callable[[Any], None]) -> None:
        """Run ``fn()`` in a worker; then ``done(result)`` on the UI thread, or report the error."""
        self.query_one(Busy).start(label)
        self._job(fn, done)

    @work(thread=True, exclusive=True, group="job", exit_on_error=False)
    def _job(self, fn: Callable[[], Any], done: Callable[[Any], None]) -> None:
        worker = get_current_worker()
        try:
            result = fn()
        except Exception as exc:  # noqa: BLE001  (shown to the operator; the app stays usable)
            if not worker.is_cancelled:
                self.app.call_from_thread(self._job_failed, exc)
            return
        if not worker.is_cancelled:
            self.app.call_from_thread(self._job_done, done, result)

    def _job_done(self, done: Callable[[Any], None], result: Any) -> None:
        self.query_one(Busy).stop()
        try:
            done(result)
        except Exception as exc:  # noqa: BLE001
            self.app.report_error(exc)

    def _job_failed(self, exc: Exception) -> None:
        self.query_one(Busy).stop()
        self.app.report_error(exc)

    @property
    def busy(self) -> bool:
        return any(w.group == "job" and not w.is_finished for w in self.workers if w.node is self)

    def action_cancel(self) -> None:
        if self.busy:
            self.workers.cancel_node(self)
            self.query_one(Busy).stop()
            self.notify("cancelled; the step's result will be discarded", title="cancel")

    def on_busy_cancel_requested(self, event: Busy.CancelRequested) -> None:
        self.action_cancel()
