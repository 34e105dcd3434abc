"""A small calibrated floor on disk, for tests that need files to run commands on."""

from __future__ import annotations

from pathlib import Path

from sbplan.detection.calibration import Calibration, calibrate
from sbplan.imageio import write_image
from sbplan.synth import FloorSpec, render_reference

#: 6 x 4 symbols on 480 x 360 pixels: calibrates in well under a second.
FLOOR = FloorSpec(width=480, height=360, cols=6, rows=4)


def calibrated_floor(folder: Path) -> Calibration:
    """Render the empty floor into ``folder/reference.png``, calibrate it (pitch 0.5 m) and save
    ``folder/cal.json``."""
    reference = render_reference(FLOOR, seed=0)
    write_image(folder / "reference.png", reference)
    cal = calibrate(reference, cell_size=0.5)
    cal.save(folder / "cal.json")
    return cal
