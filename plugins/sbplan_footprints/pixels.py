"""Footprints refined from the pixels in and around the occupied cells (sbplan.detection.footprints)."""

from __future__ import annotations

from dataclasses import dataclass

from sbplan.contracts import FootprintRefiner, option
from sbplan.detection.footprints import SUPPORT, TEXTURE_SEED, cell_outlines, footprint_reference, pixel_outlines


@dataclass(kw_only=True, frozen=True)
class PixelsFootprint(FootprintRefiner):
    """Each obstacle's outline found in the frame against the reference (sbplan.detection.footprints):
    seeds from the occupied cells' hidden and visible symbol edges, a watershed over the frame's log
    grey levels, supported pieces, convex bays filled, a 4 px margin. Falls back to the cells for
    calibrations without the reference thumbnail.
    """

    name = "pixels"
    fallback = "cells"
    description = "outlines refined from the pixels in and around the occupied cells (the default)"
    reach: float = option(1.0, "cells beyond the occupied ones an obstacle is looked for in")
    margin: int = option(1, "pixels of the 4x smaller image (4 px each) the found region is grown by")
    texture_seed: float = option(TEXTURE_SEED, "texture level taken for an obstacle's print in an occupied cell (0: off)")
    neck: int = option(3, "opening (4 px units) parting pieces before their convex hulls (0: no hulls)")
    support: float = option(SUPPORT, "share of changed pixels a piece outside the occupied cells needs to stay (0: off)")

    def prepare(self, calibration):
        return footprint_reference(calibration)

    def outlines(self, gray, occupied, occupancy, calibration, camera, prepared):
        if prepared is None:  # detection switches to the fallback; called directly, give the same
            return cell_outlines(occupancy, occupied, calibration.grid)
        return pixel_outlines(gray, occupied, prepared, camera=camera, reach=self.reach, margin=self.margin,
                              texture_seed=self.texture_seed, neck=self.neck, support=self.support)
