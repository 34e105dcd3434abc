"""A minimal matcher plugin: write a DescriptorMatcher, check it, register it, detect with it.

Run it from the repository root (it takes a few seconds):

    python examples/minimal_matcher_plugin.py

A matcher turns a symbol's outline into a short vector (its descriptor) and says how far apart two
descriptors are. Detection calls a cell free when the outline found there is close enough to the
reference symbol's. This one describes an outline by three numbers that ignore where the outline
is, its size, its rotation and where it starts. An installed plugin registers its classes through
the ``sbplan`` entry-point group (docs/plugin-guide.md); here the class is registered in this
process only, which is handy while writing one.
"""

from dataclasses import dataclass
from typing import ClassVar

import cv2
import numpy as np

import sbplan
from sbplan.contours import as_points
from sbplan.contracts import DescriptorMatcher
from sbplan.registry import matcher_names
from sbplan.testing import check_stage, registered

MAP = "maps/paper-8x6"


# 1. The stage: a frozen dataclass (options would be its fields) subclassing the contract.
@dataclass(frozen=True)
class ShapeRatiosMatcher(DescriptorMatcher):
    """Roundness, convexity and elongation of the outline; Euclidean distance."""

    name: ClassVar[str] = "shape-ratios"
    # distances below this mean "the same shape" until a calibration derives a better threshold
    default_threshold: ClassVar[float] = 0.1

    def describe(self, points: np.ndarray) -> np.ndarray:
        p = as_points(points).astype(np.float32)  # (N, 2) x, y; validated: N >= 3, finite
        area = abs(cv2.contourArea(p))
        perimeter = cv2.arcLength(p, closed=True)
        hull_area = cv2.contourArea(cv2.convexHull(p))
        m = cv2.moments(p)  # second moments of the enclosed area give its two axes
        mu20, mu02, mu11 = m["mu20"], m["mu02"], m["mu11"]
        spread = np.hypot(mu20 - mu02, 2 * mu11)
        axes = ((mu20 + mu02 - spread) / (mu20 + mu02 + spread)) ** 0.5
        return np.array([4 * np.pi * area / perimeter**2, area / hull_area, axes])

    def distance_matrix(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        a, b = np.atleast_2d(a), np.atleast_2d(b)  # (n, 3) and (m, 3) -> (n, m)
        return np.linalg.norm(a[:, None, :] - b[None, :, :], axis=-1)


# 2. The plugin kit checks the contract (output sizes, symmetry, invariance, discrimination) and
#    raises AssertionError naming the first broken rule. No pytest needed.
check_stage(ShapeRatiosMatcher())
print("shape-ratios: the matcher contract holds")

# 3. Register the class in this process, for the `with` block: inside it the matcher is found by
#    name like a built-in one (sbplan.registry.registry().add(cls) would keep it for good).
with registered(ShapeRatiosMatcher, origin="examples/minimal_matcher_plugin.py"):
    print("matchers:", ", ".join(matcher_names()))

    # 4. Detect with it. Calibration derives the match threshold for the chosen matcher from the
    #    reference's own symbols, so the same call works for any matcher.
    calibration = sbplan.calibrate(f"{MAP}/reference.png", workspace=MAP, matcher="shape-ratios")
    print(f"threshold derived by calibration: {calibration.threshold:.4f}")
    ours = sbplan.detect(f"{MAP}/scene-01.png", calibration)
    print(f"{ours.stages['matcher']}: {len(ours.occupied_cells)} occupied cells, {len(ours.obstacles)} obstacles")

print("after the block, matchers:", ", ".join(matcher_names()))
default = sbplan.detect(f"{MAP}/scene-01.png", sbplan.calibrate(f"{MAP}/reference.png", workspace=MAP))
print(f"{default.stages['matcher']} (the default): {len(default.occupied_cells)} occupied cells, "
      f"{len(default.obstacles)} obstacles")
print("same cells as the default matcher:", ours.occupied_cells == default.occupied_cells)
