"""Snapshots of every screen of ``sbplan tui`` on maps/paper-8x6 (pytest-textual-snapshot), at
80 x 24 (the side panel under the picture, keys on two rows where one cannot hold them) and at
140 x 45.

Deterministic by construction: fixed terminal sizes, half-block pictures (no terminal graphics),
timings shown as ``···`` (hide_timings), paths relative to the checkout, no toasts. Update with
``python3 -m pytest tests/test_tui_snapshots.py --snapshot-update`` and look at the SVGs.
"""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("textual")
pytest.importorskip("pytest_textual_snapshot")

from textual.widgets import DataTable  # noqa: E402

from sbplan.tui.app import SbplanApp  # noqa: E402
from sbplan.tui.session import point_along  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
MAP = "maps/paper-8x6"
SIZES = [(80, 24), (140, 45)]

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


def tables_pending(app) -> bool:
    """A DataTable sizes its columns to new rows only when it next goes idle."""
    return any(t._require_update_dimensions or t._updated_cells or t._new_rows for t in app.screen.query(DataTable))


async def quiet(pilot) -> None:
    """No toasts in the picture (they come and go with time), and every DataTable's columns sized
    to its rows: waited for as a condition, since on a loaded machine a widget can reach idle
    after any fixed number of pauses."""
    await settle(pilot)
    pilot.app.clear_notifications()
    await pilot.pause()
    for _ in range(200):
        if not tables_pending(pilot.app):
            break
        await pilot.pause(0.02)
    assert not tables_pending(pilot.app)
    await pilot.pause()


async def detected(pilot) -> None:
    """Calibrated on its own, then screen 2, which detects on its own on first show."""
    await settle(pilot)
    await pilot.press("2")
    await settle(pilot)


async def zoomed(pilot) -> None:
    """The detection picture full screen, 1.5 x about the middle: obstacle numbers stay text."""
    await detected(pilot)
    await pilot.press("f")
    await pilot.press("plus")


async def replanned(pilot) -> None:
    """Screen 3 plans on its own on first show; a dynamic obstacle ahead of the robot replans."""
    await detected(pilot)
    await pilot.press("3")
    await settle(pilot)
    app = pilot.app
    view = app.screen.query_one("#map")
    x, y = point_along(app.session.route.waypoints, 0.6)
    view.set_cursor((round(x, 1), round(y, 1)))
    await pilot.press("o")


async def helped(pilot) -> None:
    await quiet(pilot)  # the reference opens and calibrates on its own; its toast goes first
    await pilot.press("f1")


#: screen -> how to get there from start-up
SCREENS = {"calibration": settle, "detection": detected, "detection-zoomed": zoomed,
           "route-after-a-replan": replanned, "help": helped}


#: every screen at both sizes; the zoomed picture at 80 x 24 only, where zoom is needed to read it
CASES = [(screen, size) for screen in SCREENS for size in SIZES
         if not (screen == "detection-zoomed" and size != (80, 24))]


@pytest.mark.parametrize("screen, size", CASES, ids=[f"{screen}-{w}x{h}" for screen, (w, h) in CASES])
def test_screen(snap_compare, screen, size):
    async def run_before(pilot):
        await SCREENS[screen](pilot)
        await quiet(pilot)

    assert snap_compare(make_app(), terminal_size=size, run_before=run_before)
