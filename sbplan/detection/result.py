"""What a detection gives: :class:`CellDetection` (the cells) and :class:`Detection` (the cells,
the occupancy image and the obstacles), and the detection JSON's format tag."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .calibration.file import Calibration
from .obstacles import DEFAULT_OBSTACLE_MODEL, Obstacle, check_obstacle_model
from .registration import CameraMotion

FORMAT = "sbplan.detection/1"


@dataclass(frozen=True, eq=False)
class Detection:
    """The result of one detection: :class:`CellDetection`'s ``occupied``, ``symbols_found``,
    ``symbols_rescued``, ``matched_centres_px``, ``candidates_px`` and ``camera``, and what is
    built on them.

    Attributes
    ----------
    occupancy : ndarray of shape (H, W), uint8
        The occupancy image (0 occupied, 255 free), paper figure 14.
    obstacles : list of Obstacle
    timings_ms : dict
        Milliseconds per stage, in pipeline order (``map``, ``footprint`` and ``obstacles`` after
        :class:`CellDetection`'s), and "total".
    stages : dict
        kind -> stage name used.
    """

    calibration: Calibration
    occupied: np.ndarray
    symbols_found: int
    matched_centres_px: np.ndarray
    occupancy: np.ndarray
    obstacles: list[Obstacle]
    timings_ms: dict[str, float]
    stages: dict[str, str]
    candidates_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    camera: CameraMotion = field(default_factory=CameraMotion.none)
    symbols_rescued: int = 0

    @property
    def occupied_cells(self) -> list[tuple[int, int]]:
        return [(int(r), int(c)) for r, c in zip(*np.nonzero(self.occupied))]

    @property
    def symbols_expected(self) -> int:
        return self.calibration.symbols_expected

    def planner_obstacles(self, model: str = DEFAULT_OBSTACLE_MODEL) -> list[np.ndarray]:
        """What the planner avoids under the obstacle model ``model`` (``mar``, ``parts`` or
        ``outline``; see :mod:`sbplan.detection.obstacles`): polygons (K, 2) in world metres, the
        obstacles' in their order."""
        check_obstacle_model(model)
        return [p for ob in self.obstacles for p in ob.polygons_m(model)]

    def to_json(self) -> dict:
        cal = self.calibration
        return {
            "format": FORMAT,
            "image": {"width": cal.image_shape[1], "height": cal.image_shape[0]},
            "grid": {"rows": cal.grid.rows, "cols": cal.grid.cols},
            "symbols_expected": self.symbols_expected,
            "symbols_found": self.symbols_found,
            "symbols_rescued": self.symbols_rescued,
            "occupied_cells": [list(c) for c in self.occupied_cells],
            "free_cells": int((~self.occupied).sum()),
            "obstacles": [o.to_json() for o in self.obstacles],
            "workspace": {
                "bounds_m": [round(v, 6) for v in cal.world_bounds()],
                "pitch_m": list(cal.workspace.pitch_m),
                "origin_m": list(cal.workspace.origin),
                "robot_radius_m": cal.workspace.robot_radius_m,
                "frame": "metres; x right along the columns, y up toward row 0",
                "georeference": (cal.workspace.georeference.to_json()
                                 if cal.workspace.georeference is not None else None),
            },
            "camera": self.camera.to_json(),
            "stages": dict(self.stages),
            "timings_ms": {k: round(v, 4) for k, v in self.timings_ms.items()},
        }


@dataclass(frozen=True, eq=False)
class CellDetection:
    """What :meth:`Detector.find_cells` gives: the cells, without occupancy image or obstacles.

    Attributes
    ----------
    occupied : ndarray of shape (rows, cols), bool
        True where the cell's symbol is missing; ``[row, col]``, row 0 at the top.
    symbols_found : int
        Symbols the matcher took for the reference symbol and the outline checks kept whole, in
        their cells: only matched symbols count.
    symbols_rescued : int
        Cells whose symbol did not match or failed the outline checks in the binary image but
        whose edge the grey image still shows all around (a shadow or glare spoiled the binary
        image): free cells that matching did not find. Free cells = found + rescued. The edge check
        rescues at most as many cells as matching found (else a DetectionError: the matcher does
        not fit).
    matched_centres_px : ndarray of shape (found + rescued, 2)
        Centres ``(x, y)`` of the symbols found in their cells, then those of the rescued cells
        (their reference symbol's centre).
    candidates_px : ndarray of shape (m, 2)
        Centres of outlines that matched the symbol's shape but were rejected (off the grid, or
        grown, shrunk or bent against their cell's reference outline).
    timings_ms : dict
        Milliseconds per stage up to "match", and "total".
    image_shape : (H, W)
    camera : CameraMotion
        The camera's movement since calibration, as this frame showed it
        (:mod:`sbplan.detection.registration`). Every pixel coordinate of the result is the calibration's.
    """

    occupied: np.ndarray
    symbols_found: int
    matched_centres_px: np.ndarray
    candidates_px: np.ndarray
    timings_ms: dict[str, float]
    image_shape: tuple[int, int]
    camera: CameraMotion = field(default_factory=CameraMotion.none)
    symbols_rescued: int = 0
