"""What the terminal app's tests share: running them with asyncio, waiting for steps, typing."""

from __future__ import annotations

import asyncio
import functools
from pathlib import Path

import pytest
from textual.widgets import Input, Static

REPO = Path(__file__).resolve().parents[1]
MAP = REPO / "maps" / "paper-8x6"
#: ``pytestmark = needs_map``: the terminal app's tests run on maps/paper-8x6
needs_map = pytest.mark.skipif(not (MAP / "reference.png").is_file(), reason="maps/paper-8x6 not built")


@pytest.fixture(autouse=True)
def in_repo(monkeypatch):
    """Paths on screen are shown relative to the working folder: the checkout (imported by a test
    module, it applies to each of its tests)."""
    monkeypatch.chdir(REPO)


def aio(fn):
    """Run an async test body with asyncio (no async pytest plugin is installed)."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        return asyncio.run(fn(*args, **kwargs))
    return wrapper


async def settle(app, pilot) -> None:
    """Let every running step finish (a cancelled one's thread too) and the screens catch up."""
    await pilot.pause()
    await app.workers.wait_for_complete()
    for _ in range(600):
        if not getattr(app.screen, "running", False):
            break
        await pilot.pause(0.05)
    await pilot.pause()


def text_of(app, selector: str) -> str:
    return str(app.screen.query_one(selector, Static).render())


def error_messages(app) -> list[str]:
    # the app's log, not the notifications: those expire after a while on a busy machine
    return list(app.error_log)


async def type_into(pilot, selector: str, text: str) -> None:
    widget = pilot.app.screen.query_one(selector, Input)
    widget.value = text
    widget.focus()
    await pilot.pause()


class RunningApp:
    """One app kept running across several tests (a module-scoped fixture holds it): starting an
    app and bringing it to a state costs far more than what most tests then do with it.

    ``run(body)`` runs ``await body(app, pilot)`` on the app's own event loop, which stands still
    between tests; a test lets its steps finish (``settle``) before it returns, so that no worker
    thread waits on the stopped loop.
    """

    def __init__(self, app, size: tuple[int, int]) -> None:
        self.app = app
        self._runner = asyncio.Runner()
        self._context = app.run_test(size=size)
        self.pilot = self._runner.run(self._context.__aenter__())

    def run(self, body):
        return self._runner.run(body(self.app, self.pilot))

    def close(self) -> None:
        try:
            self._runner.run(self._context.__aexit__(None, None, None))
        finally:
            self._runner.close()
