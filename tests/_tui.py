"""What the terminal app's tests share: running them with asyncio, waiting for steps, typing."""

from __future__ import annotations

import asyncio
import functools

from textual.widgets import Input, Static


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


async def calibrated_and_detected(app, pilot) -> None:
    """With ``auto=False``: calibrate on the opened reference (screen 1), detect (screen 2)."""
    await settle(app, pilot)  # the reference opens on its own
    await pilot.press("c")
    await settle(app, pilot)
    await pilot.press("2")
    await pilot.press("d")
    await settle(app, pilot)
