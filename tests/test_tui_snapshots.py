"""Snapshots of every screen of ``sbplan tui`` on maps/paper-8x6 (pytest-textual-snapshot).

Deterministic by construction: a fixed terminal size, half-block pictures (no terminal graphics),
timings shown as ``···`` (hide_timings), paths relative to the checkout, no toasts. Update with
``python3 -m pytest tests/test_tui_snapshots.py --snapshot-update`` and look at the SVGs.
"""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("textual")
pytest.importorskip("pytest_textual_snapshot")

from sbplan.tui.app import SbplanApp  # noqa: E402
from sbplan.tui.session import point_along  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
MAP = "maps/paper-8x6"
SIZE = (160, 48)

pytestmark = pytest.mark.skipif(not (REPO / MAP / "reference.png").is_file(), reason="maps/paper-8x6 not built")


@pytest.fixture(autouse=True)
def _in_repo(monkeypatch):
    monkeypatch.chdir(REPO)


def make_app() -> SbplanApp:
    from textual_image.widget import HalfcellImage

    return SbplanApp(MAP, auto=True, image_class=HalfcellImage, hide_timings=True)


async def settle(pilot) -> None:
    app = pilot.app
    await pilot.pause()
    await app.workers.wait_for_complete()
    await pilot.pause()


async def quiet(pilot) -> None:
    """No toasts in the picture: they come and go with time.

    A DataTable sizes its columns to new rows only when it next goes idle, which on a loaded
    machine can come after one ``pause()``; a few short real-time pauses let every widget reach idle.
    """
    await settle(pilot)
    pilot.app.clear_notifications()
    for _ in range(3):
        await pilot.pause(0.05)


def test_calibration_screen(snap_compare):
    async def run_before(pilot):
        await settle(pilot)  # the reference opens and calibrates on its own
        await quiet(pilot)

    assert snap_compare(make_app(), terminal_size=SIZE, run_before=run_before)


def test_detection_screen(snap_compare):
    async def run_before(pilot):
        await settle(pilot)
        await pilot.press("2")
        await settle(pilot)  # detects on its own on first show
        await quiet(pilot)

    assert snap_compare(make_app(), terminal_size=SIZE, run_before=run_before)


def test_route_screen_after_a_replan(snap_compare):
    async def run_before(pilot):
        await settle(pilot)
        await pilot.press("2")
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)  # plans on its own on first show
        app = pilot.app
        view = app.screen.query_one("#map")
        x, y = point_along(app.session.route.waypoints, 0.6)
        view.set_cursor((round(x, 1), round(y, 1)))
        await pilot.press("o")
        await quiet(pilot)

    assert snap_compare(make_app(), terminal_size=SIZE, run_before=run_before)


def test_help_screen(snap_compare):
    async def run_before(pilot):
        await settle(pilot)
        await quiet(pilot)

    assert snap_compare(make_app(), press=["f1"], terminal_size=SIZE, run_before=run_before)
