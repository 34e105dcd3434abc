"""A picture of the live state: the frame with the stable occupied cells, the obstacles and the route."""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

from ..detection.exports import _BLACK, _GREEN, _RED, _WHITE, _YELLOW
from .watcher import LiveState

if TYPE_CHECKING:
    from ..detection.calibration import Calibration


def world_to_pixels(calibration: Calibration, xy: np.ndarray) -> np.ndarray:
    """World metres ``(x, y)`` (N, 2) -> the calibration's pixels ``(x, y)`` (N, 2), through the grid
    (the inverse of :meth:`~sbplan.detection.calibration.Calibration.pixels_to_world`)."""
    ws, rows = calibration.workspace, calibration.grid.rows
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    ox, oy = ws.origin
    lattice = np.column_stack([(p[:, 0] - ox) / ws.pitch_m[0], rows - 1 - (p[:, 1] - oy) / ws.pitch_m[1]])
    return calibration.grid.lattice_to_px(lattice)


def live_overlay(image: np.ndarray, state: LiveState, calibration: Calibration) -> np.ndarray:
    """``image`` (the frame, gray or BGR) with the state drawn where the camera's movement puts it:
    stable occupied cells shaded red, obstacle MARs yellow with their ids, the route green.
    Returns BGR ``(H, W, 3)`` uint8."""
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    out = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    cam = state.camera
    to_frame = cam.to_frame if cam is not None and cam.moved else (lambda xy: np.asarray(xy, dtype=np.float64))
    corners = to_frame(calibration.grid.cell_corners_px())
    scale = max(1, round(min(gray.shape) / 500))
    if state.occupied.any():
        shade = out.copy()
        for r, c in zip(*np.nonzero(state.occupied)):
            quad = np.array([corners[r, c], corners[r, c + 1], corners[r + 1, c + 1], corners[r + 1, c]])
            cv2.fillPoly(shade, [np.rint(quad * 16).astype(np.int32)], _RED, lineType=cv2.LINE_AA, shift=4)
        out = cv2.addWeighted(shade, 0.35, out, 0.65, 0)
    for ob in state.obstacles:
        cv2.polylines(out, [np.rint(to_frame(ob.mar_px) * 16).astype(np.int32)], True, _YELLOW, 2 * scale,
                      cv2.LINE_AA, shift=4)
        cx, cy = to_frame(np.asarray(ob.centre_px, dtype=np.float64))
        label = str(ob.id)
        font, fs, th = cv2.FONT_HERSHEY_SIMPLEX, 0.9 * scale, 2 * scale
        (tw, tht), _ = cv2.getTextSize(label, font, fs, th)
        org = (int(cx - tw / 2), int(cy + tht / 2))
        cv2.putText(out, label, org, font, fs, _BLACK, th + 3 * scale, cv2.LINE_AA)
        cv2.putText(out, label, org, font, fs, _WHITE, th, cv2.LINE_AA)
    if state.route is not None and len(state.route.waypoints) >= 2:
        pts = to_frame(world_to_pixels(calibration, state.route.waypoints))
        cv2.polylines(out, [np.rint(pts * 16).astype(np.int32)], False, _GREEN, 3 * scale, cv2.LINE_AA, shift=4)
        for p, text in ((pts[0], "S"), (pts[-1], "G")):
            cv2.circle(out, (int(round(p[0])), int(round(p[1]))), 6 * scale, _GREEN, -1, cv2.LINE_AA)
            cv2.putText(out, text, (int(p[0]) + 8 * scale, int(p[1]) - 8 * scale), cv2.FONT_HERSHEY_SIMPLEX,
                        0.6 * scale, _WHITE, scale, cv2.LINE_AA)
    return out
