"""The tiny rendered floor, its calibrated pipeline, and stages registered for a while: what the
fixtures hand out, usable without pytest."""

from __future__ import annotations

import contextlib
import functools
from dataclasses import dataclass
from typing import Iterator, Unpack

import numpy as np

from .. import registry
from ..contracts import Stage, StageChoices
from ..detection import Calibration, CellDetection, Detection, Detector
from ..detection.calibration import calibrate
from ..errors import PluginError
from ..synth import FloorSpec, SceneSpec, render_reference, render_scene
from ..synth.truth import GroundTruth


@dataclass(frozen=True, eq=False)
class TinyFloor:
    """A small rendered floor (see :func:`make_tiny_floor`).

    Attributes
    ----------
    spec : sbplan.synth.FloorSpec
    reference : ndarray of shape (H, W), uint8
        The empty floor, every symbol visible.
    scene : ndarray of shape (H, W), uint8
        The same floor with obstacles.
    truth : sbplan.synth.GroundTruth
        ``truth.cells[row, col]``: 1 occupied, 0 free, -1 ambiguous (a sliver covered).
    """

    spec: FloorSpec
    reference: np.ndarray
    scene: np.ndarray
    truth: GroundTruth

    @property
    def occupied(self) -> np.ndarray:
        """Truly occupied cells, shape (rows, cols), bool, ``[row, col]``."""
        return self.truth.cells == 1

    @property
    def ambiguous(self) -> np.ndarray:
        """Cells whose symbol is covered by a sliver only: either answer is acceptable."""
        return self.truth.cells == -1


@functools.lru_cache(maxsize=8)
def make_tiny_floor(*, seed: int = 3, n_obstacles: int = 2, condition: str = "clean", width: int = 320,
                    height: int = 240, cols: int = 4, rows: int = 3, pitch: tuple[float, float] = (78.6, 77.2)) -> TinyFloor:
    """Render a small floor and one scene on it; cached, the arrays are read-only.

    Parameters
    ----------
    seed : int
        Seed of the scene (obstacles, noise). The reference uses seed 0.
    n_obstacles : int
    condition : str
        A name of ``sbplan.synth.CONDITIONS`` (``clean``, ``shadows``, ``highlights``, ...).
    width, height, cols, rows : int
        Image size in pixels and symbol grid.
    pitch : (dx, dy)
        Symbol spacing in pixels. Not a whole number on purpose: every symbol then falls on the
        pixel grid differently, so the reference's symbols are not pixel-identical copies (as on
        a real floor) and a calibration sees their true spread.
    """
    spec = FloorSpec(width=width, height=height, cols=cols, rows=rows, pitch=pitch)
    reference = render_reference(spec, seed=0)
    scene, truth = render_scene(spec, SceneSpec(n_obstacles=n_obstacles, condition=condition), seed=seed)
    for a in (reference, scene):
        a.setflags(write=False)
    return TinyFloor(spec, reference, scene, truth)


@dataclass(frozen=True, eq=False)
class CalibratedPipeline:
    """A calibration of a :class:`TinyFloor` and detection on its scene."""

    floor: TinyFloor
    calibration: Calibration

    def detect(self, image: np.ndarray | None = None, **stages: Unpack[StageChoices]) -> Detection:
        """Detection on ``image`` (default: the floor's scene) with stage overrides by name or instance.

        A matcher other than the calibrated one gets its reference descriptor and threshold from
        :meth:`~sbplan.detection.Calibration.matching_for`.
        """
        return Detector(self.calibration, **stages)(self.floor.scene if image is None else image)

    def cell_errors(self, detection: Detection | CellDetection) -> int:
        """Cells where ``detection`` disagrees with the ground truth, ambiguous cells not counted."""
        wrong = detection.occupied != self.floor.occupied
        return int((wrong & ~self.floor.ambiguous).sum())


def make_calibrated_pipeline(floor: TinyFloor | None = None, **stages: Unpack[StageChoices]) -> CalibratedPipeline:
    """Calibrate on ``floor.reference`` (default: :func:`make_tiny_floor`) with optional stages."""
    floor = floor or make_tiny_floor()
    return CalibratedPipeline(floor, calibrate(floor.reference, **stages))


@contextlib.contextmanager
def registered(*classes: type[Stage], origin: str = "test") -> Iterator[None]:
    """Register stage classes in the process-wide registry for the duration of a ``with`` block.

    A stage already registered under the same kind and name is replaced and put back afterwards.
    """
    reg = registry.registry()
    previous = []
    try:
        for cls in classes:
            try:
                old = reg.info(cls.kind, cls.name)
            except (PluginError, AttributeError):
                old = None
            reg.add(cls, origin=origin, replace=True)
            previous.append((cls.kind, cls.name, old))
        yield
    finally:
        for kind, name, old in reversed(previous):
            reg.remove(kind, name)
            if old is not None:
                reg.add(old.cls, origin=old.origin, replace=True)
