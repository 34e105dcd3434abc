"""Cell-level accuracy of detection against the renderer's ground truth.

Ground truth names each cell occupied, free or ambiguous (a sliver of overlap); ambiguous cells are
left out of the score. A cell is a true positive when it is occupied in both.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterator

import numpy as np

from ..errors import InputError
from ..synth import FloorSpec, GroundTruth, SceneSpec, render_reference, render_scene


@dataclass(frozen=True)
class Scores:
    tp: int = 0
    fp: int = 0
    fn: int = 0
    tn: int = 0

    def __add__(self, other: "Scores") -> "Scores":
        return Scores(self.tp + other.tp, self.fp + other.fp, self.fn + other.fn, self.tn + other.tn)

    @property
    def precision(self) -> float:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else 1.0

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else 1.0

    @property
    def f1(self) -> float:
        denominator = 2 * self.tp + self.fp + self.fn
        return 2 * self.tp / denominator if denominator else 1.0


def score_cells(predicted: np.ndarray, truth: np.ndarray) -> Scores:
    """Compare predicted occupancy with ground truth.

    Parameters
    ----------
    predicted : ndarray of shape (rows, cols), bool
        True where a cell is called occupied.
    truth : ndarray of shape (rows, cols), int
        1 occupied, 0 free, -1 ambiguous (excluded).
    """
    predicted, truth = np.asarray(predicted, bool), np.asarray(truth)
    if predicted.shape != truth.shape:
        raise InputError(f"predicted: shape {predicted.shape} differs from the ground truth's {truth.shape}")
    known = truth >= 0
    occ = truth == 1
    return Scores(
        tp=int((predicted & occ & known).sum()),
        fp=int((predicted & ~occ & known).sum()),
        fn=int((~predicted & occ & known).sum()),
        tn=int((~predicted & ~occ & known).sum()),
    )


def condition_scenes(condition: str, *, scenes: int = 5, size: tuple[int, int] = (1280, 960),
                     grid: tuple[int, int] = (10, 5), seed: int = 0, layout: str | None = None,
                     **floor_options: Any) -> Iterator[tuple[np.ndarray, np.ndarray, GroundTruth]]:
    """Yield ``(reference, scene, truth)`` for one condition of the renderer's suite, seeded.

    The reference shares the scenes' camera (tilt, distortion) and is lit with base lighting.
    """
    width, height = size
    cols, rows = grid
    extra = dict(floor_options)
    if layout is not None:
        extra["layout"] = layout
    floor = FloorSpec(width=width, height=height, cols=cols, rows=rows, **extra)
    reference = render_reference(floor, seed=seed, condition=condition)
    for k in range(scenes):
        image, truth = render_scene(floor, SceneSpec(condition=condition), seed=seed * 1000 + k + 1)
        yield reference, image, truth
