"""The paper's footprint: each obstacle is the union of its occupied cells."""

from __future__ import annotations

from dataclasses import dataclass

from sbplan.contracts import FootprintRefiner
from sbplan.detection.footprints import cell_outlines


@dataclass(kw_only=True, frozen=True)
class CellsFootprint(FootprintRefiner):
    """The occupancy image's black regions, as the paper outlines obstacles (section 4.1)."""

    name = "cells"
    description = "the occupied cells' regions (the paper's outlines)"

    def outlines(self, gray, occupied, occupancy, calibration, camera, prepared):
        return cell_outlines(occupancy, occupied, calibration.grid)
