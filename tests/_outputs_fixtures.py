"""One calibration and detection of the paper floor (maps/paper-8x6) per test session, shared by
the output tests (GeoJSON, nav2, schemas, logging): calibrating takes a few seconds."""

from __future__ import annotations

import functools
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "maps" / "paper-8x6"


@functools.cache
def paper():
    """(calibration, detection, scene image) of maps/paper-8x6's scene-01."""
    from sbplan.detection import Detector
    from sbplan.detection.calibration import calibrate
    from sbplan.imageio import load_image
    from sbplan.workspace import load_workspace

    cal = calibrate(PAPER / "reference.png", workspace=load_workspace(PAPER))
    image = load_image(PAPER / "scene-01.png")
    return cal, Detector(cal)(image), image


@functools.cache
def moved_floor():
    """(calibration, frame) on a rendered 8 x 5 floor whose camera moved enough for a warning
    (shift (4, -3) px, 0.4 degrees) after calibration, with 3 obstacles."""
    from sbplan.detection.calibration import calibrate
    from sbplan.synth import FloorSpec, SceneSpec, render_reference, render_scene

    floor = FloorSpec(width=800, height=600, cols=8, rows=5)
    cal = calibrate(render_reference(floor, seed=0))
    image, _ = render_scene(floor, SceneSpec(n_obstacles=3, effects={"motion": (4.0, -3.0, 0.4, 1.0)}), seed=3)
    return cal, image

