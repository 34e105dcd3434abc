"""Ground truth of a rendered scene."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..imageio import json_default
from ..errors import MapFormatError

#: Cell states in :attr:`GroundTruth.cells`.
OCCUPIED, FREE, AMBIGUOUS = 1, 0, -1
FORMAT = "sbplan-truth/1"


@dataclass(eq=False)
class GroundTruth:
    """What a scene really shows.

    Attributes
    ----------
    cells : ndarray (rows, cols) int8
        1 occupied (more than ``occupied_fraction`` of the symbol's area covered), 0 free (no
        overlap, no obstacle within ``near_px``), -1 ambiguous (a sliver). Row 0 = top row.
    overlap : ndarray (rows, cols) float
        Fraction of each symbol's area covered by obstacles, in the floor plane.
    centres_px : ndarray (rows, cols, 2) float
        True symbol centres of area ``(x, y)`` in the image (after the camera).
    obstacles : list of ndarray (K, 2) float
        Obstacle outlines ``(x, y)`` in image pixels (after the camera).
    obstacles_floor : list of ndarray (K, 2) float
        The same outlines in the floor plane (before the camera).
    kinds, textures : list of str
        Per obstacle.
    params : dict
        Every parameter used: ``floor``, ``scene``, ``effects``, ``seed``, ``occupied_fraction``,
        ``near_px`` and the derived lighting draws.
    """

    cells: np.ndarray
    overlap: np.ndarray
    centres_px: np.ndarray
    obstacles: list
    obstacles_floor: list
    kinds: list = field(default_factory=list)
    textures: list = field(default_factory=list)
    params: dict = field(default_factory=dict)

    @property
    def occupied(self) -> np.ndarray:
        return self.cells == OCCUPIED

    def motion_matrix(self) -> np.ndarray:
        """The camera's movement since calibration (3x3, calibration pixels -> this image's pixels;
        the identity when the camera did not move)."""
        motion = self.params.get("camera", {}).get("motion")
        return np.asarray(motion["matrix"], dtype=np.float64) if motion else np.eye(3)

    def obstacle_masks(self, shape: tuple[int, int], *, calibration_pixels: bool = True) -> list[np.ndarray]:
        """Each obstacle's true pixels: the pixels whose centres its outline holds.

        Parameters
        ----------
        shape : (H, W)
        calibration_pixels : bool
            True: in the calibration's view (the image before the camera moved, where detection
            results are); False: in this image's pixels (:attr:`obstacles` as they are).

        Returns
        -------
        list of ndarray (H, W), bool, one per obstacle of :attr:`obstacles`.
        """
        import cv2

        inverse = np.linalg.inv(self.motion_matrix()) if calibration_pixels else np.eye(3)
        out = []
        for p in self.obstacles:
            q = np.c_[np.asarray(p, dtype=np.float64), np.ones(len(p))] @ inverse.T
            q = q[:, :2] / q[:, 2:]
            m = np.zeros(shape, np.uint8)
            cv2.fillPoly(m, [np.rint(q * 16).astype(np.int32)], 1, cv2.LINE_8, shift=4)
            out.append(m.astype(bool))
        return out

    @property
    def counts(self) -> dict[str, int]:
        return {"occupied": int((self.cells == OCCUPIED).sum()), "free": int((self.cells == FREE).sum()),
                "ambiguous": int((self.cells == AMBIGUOUS).sum())}

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "counts": self.counts,
            "cells": self.cells.astype(int).tolist(),
            "overlap": np.round(self.overlap, 6).tolist(),
            "centres_px": np.round(self.centres_px, 4).tolist(),
            "obstacles": [np.round(o, 4).tolist() for o in self.obstacles],
            "obstacles_floor": [np.round(o, 4).tolist() for o in self.obstacles_floor],
            "kinds": list(self.kinds),
            "textures": list(self.textures),
            "params": self.params,
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=1, default=json_default) + "\n"

    @classmethod
    def from_json(cls, source: str | os.PathLike | dict) -> "GroundTruth":
        """Read ground truth from a dict, a JSON string or a JSON file path."""
        if isinstance(source, dict):
            d = source
        else:
            text = str(source)
            if isinstance(source, os.PathLike) or not text.lstrip().startswith("{"):
                p = Path(source)
                if not p.is_file():
                    raise MapFormatError(f"{p}: no such ground-truth file")
                text = p.read_text(encoding="utf-8")
            try:
                d = json.loads(text)
            except json.JSONDecodeError as exc:
                raise MapFormatError(f"ground truth: not JSON ({exc})") from None
        if d.get("format") != FORMAT:
            raise MapFormatError(f"ground truth: format is {d.get('format')!r}, expected {FORMAT!r}")
        try:
            return cls(
                cells=np.asarray(d["cells"], dtype=np.int8),
                overlap=np.asarray(d["overlap"], dtype=np.float64),
                centres_px=np.asarray(d["centres_px"], dtype=np.float64),
                obstacles=[np.asarray(o, dtype=np.float64) for o in d["obstacles"]],
                obstacles_floor=[np.asarray(o, dtype=np.float64) for o in d["obstacles_floor"]],
                kinds=list(d.get("kinds", [])), textures=list(d.get("textures", [])),
                params=dict(d.get("params", {})),
            )
        except KeyError as exc:
            raise MapFormatError(f"ground truth: missing key {exc}") from None
