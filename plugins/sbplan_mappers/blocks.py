"""The paper's occupancy image: the image divided into M x N rectangular blocks (section 4.1)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sbplan.contracts import OccupancyMapper


@dataclass(kw_only=True, frozen=True)
class BlocksMapper(OccupancyMapper):
    """Axis-aligned blocks, one per cell, split halfway between neighbouring columns and rows.

    The outermost blocks reach the image border, as in the paper's figure 14. Exact for a camera
    looking straight down; under tilt the blocks drift off the true cells (use ``cells``).
    """

    name = "blocks"
    description = "the paper's M x N rectangular blocks of the image (camera straight down)"

    def occupancy_image(self, grid, occupied: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        h, w = shape
        xs = np.median(grid.centres_px[:, :, 0], axis=0)  # one x per column
        ys = np.median(grid.centres_px[:, :, 1], axis=1)  # one y per row
        x_edges = np.concatenate([[0], np.rint((xs[:-1] + xs[1:]) / 2), [w]]).astype(int)
        y_edges = np.concatenate([[0], np.rint((ys[:-1] + ys[1:]) / 2), [h]]).astype(int)
        x_edges, y_edges = np.clip(x_edges, 0, w), np.clip(y_edges, 0, h)
        image = np.full((h, w), 255, np.uint8)
        for r, c in zip(*np.nonzero(occupied)):
            image[y_edges[r]:y_edges[r + 1], x_edges[c]:x_edges[c + 1]] = 0
        return image
