"""Synthetic floors: reference images, scenes with obstacles, ground truth, and the example maps.

>>> from sbplan.synth import FloorSpec, SceneSpec, render_reference, render_scene
>>> floor = FloorSpec(width=640, height=480, cols=8, rows=6)
>>> ref = render_reference(floor, seed=0)
>>> img, truth = render_scene(floor, SceneSpec(n_obstacles=3, condition="shadows"), seed=1)
"""

from __future__ import annotations

from .conditions import CONDITIONS, Effects, condition_effects
from .floor import DEFAULT_SYMBOL, LAYOUTS, OBSTACLE_KINDS, TEXTURES, FloorSpec, SceneSpec, rings_centroid, symbol_outline
from .render import PATTERNS, render_reference, render_scene
from .truth import AMBIGUOUS, FREE, OCCUPIED, GroundTruth

__all__ = [
    "AMBIGUOUS", "CONDITIONS", "DEFAULT_SYMBOL", "Effects", "FREE", "FloorSpec", "GroundTruth", "LAYOUTS",
    "OBSTACLE_KINDS", "OCCUPIED", "PATTERNS", "SceneSpec", "TEXTURES", "condition_effects", "render_reference",
    "render_scene", "rings_centroid", "symbol_outline",
]
