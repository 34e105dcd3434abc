"""Files a user can open: overlay picture, occupancy image, GeoJSON, and a ROS 2 nav2 map.

All writers are atomic. World coordinates are metres, x right along the columns, y up (nav2's frame).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import cv2
import numpy as np

from .. import limits
from ..errors import InputError
from ..files import write_atomic, write_file_set
from ..imageio import as_gray, encode_image, write_image
from ..polygons import signed_area
from .result import Detection

_RED, _GREEN, _YELLOW, _CYAN, _WHITE, _BLACK = (40, 40, 230), (60, 200, 60), (0, 220, 255), (230, 200, 0), (255, 255, 255), (0, 0, 0)


def overlay_image(image: np.ndarray, detection: Detection, *, caption: bool = True) -> np.ndarray:
    """The scene with occupied cells shaded red, found symbols marked green, MARs in yellow and
    obstacle numbers (as the paper's figure 12).

    The detection's pixel coordinates are the calibration's; they are drawn where the camera's
    movement (``detection.camera``) puts them in this frame.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, 3)
        The frame the detection was made on.
    detection : Detection
    caption : bool
        Add a caption band above the scene (symbols found, occupied cells, obstacles), so that
        it hides none of the scene.

    Returns
    -------
    ndarray of shape (H + band, W, 3), uint8, BGR
        The scene's pixels are rows ``band:`` (``band`` is 0 without the caption).
    """
    gray = as_gray(image)
    out = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    grid = detection.calibration.grid
    cam = detection.camera
    to_frame = cam.to_frame if cam.moved else (lambda xy: np.asarray(xy, dtype=np.float64))
    corners = to_frame(grid.cell_corners_px())
    shade = out.copy()
    for r, c in detection.occupied_cells:
        quad = np.array([corners[r, c], corners[r, c + 1], corners[r + 1, c + 1], corners[r + 1, c]])
        cv2.fillPoly(shade, [np.rint(quad * 16).astype(np.int32)], _RED, lineType=cv2.LINE_AA, shift=4)
    out = cv2.addWeighted(shade, 0.35, out, 0.65, 0)
    scale = max(1, round(min(gray.shape) / 500))
    for x, y in to_frame(detection.matched_centres_px.reshape(-1, 2)):
        cv2.circle(out, (int(round(x)), int(round(y))), 3 * scale, _GREEN, -1, cv2.LINE_AA)
    for x, y in to_frame(detection.candidates_px.reshape(-1, 2)):
        cv2.drawMarker(out, (int(round(x)), int(round(y))), _CYAN, cv2.MARKER_TILTED_CROSS, 8 * scale, scale)
    for ob in detection.obstacles:
        cv2.polylines(out, [np.rint(to_frame(ob.outline_px) * 16).astype(np.int32)], True, _RED, scale,
                      cv2.LINE_AA, shift=4)
        cv2.polylines(out, [np.rint(to_frame(ob.mar_px) * 16).astype(np.int32)], True, _YELLOW, 2 * scale,
                      cv2.LINE_AA, shift=4)
        label = str(ob.id)
        font, fs, th = cv2.FONT_HERSHEY_SIMPLEX, 0.9 * scale, 2 * scale
        (tw, tht), _ = cv2.getTextSize(label, font, fs, th)
        cx, cy = to_frame(np.asarray(ob.centre_px, dtype=np.float64))
        org = (int(cx - tw / 2), int(cy + tht / 2))
        cv2.putText(out, label, org, font, fs, _BLACK, th + 3 * scale, cv2.LINE_AA)
        cv2.putText(out, label, org, font, fs, _WHITE, th, cv2.LINE_AA)
    if not caption:
        return out
    rescued = f" (+{detection.symbols_rescued} by edge)" if detection.symbols_rescued else ""
    text = (f"{detection.symbols_found}/{detection.symbols_expected} symbols{rescued}, "
            f"{len(detection.occupied_cells)} occupied cells, {len(detection.obstacles)} obstacles")
    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.55 * scale, scale)
    # the caption gets its own band: drawn over the scene it hid the top row of symbols
    band = np.full((th + base + 10 * scale, out.shape[1], 3), 40, np.uint8)
    cv2.putText(band, text, (8 * scale, th + 5 * scale), cv2.FONT_HERSHEY_SIMPLEX, 0.55 * scale, _WHITE, scale,
                cv2.LINE_AA)
    return np.concatenate([band, out])


def write_overlay(path: str | os.PathLike, image: np.ndarray, detection: Detection) -> Path:
    return write_image(path, overlay_image(image, detection))


def write_occupancy(path: str | os.PathLike, detection: Detection) -> Path:
    """The occupancy image (paper figure 14): black occupied blocks on white."""
    return write_image(path, detection.occupancy)


def geojson(detection: Detection) -> dict:
    """Obstacles as a GeoJSON FeatureCollection in the local metric frame (metres, y up).

    Each obstacle gives two Polygon features: its outline (``kind: "outline"``) and its MAR
    (``kind: "mar"``). The foreign member ``sbplan`` records the frame and the floor's bounds.
    """
    features = []
    for ob in detection.obstacles:
        for kind, ring in (("outline", ob.outline_m), ("mar", ob.mar_m)):
            ring = np.asarray(ring, np.float64)
            # RFC 7946: exterior rings counter-clockwise in the y-up world frame, which is clockwise
            # in geometry.signed_area's y-down convention; first point repeated
            if signed_area(ring) > 0:
                ring = ring[::-1]
            coords = np.vstack([ring, ring[:1]]).round(6).tolist()
            features.append({
                "type": "Feature",
                "geometry": {"type": "Polygon", "coordinates": [coords]},
                "properties": {"id": ob.id, "kind": kind, "cells": [list(c) for c in ob.cells]},
            })
    return {
        "type": "FeatureCollection",
        "features": features,
        "sbplan": {
            "frame": "local metric frame: metres, x right along the grid's columns, y up toward row 0",
            "bounds_m": [round(v, 6) for v in detection.calibration.world_bounds()],
        },
    }


def write_geojson(path: str | os.PathLike, detection: Detection) -> Path:
    return write_atomic(path, json.dumps(geojson(detection), indent=1) + "\n")


#: What a nav2 map folder written by :func:`write_nav2` holds.
NAV2_FILES = ("map.yaml", "map.pgm")


def nav2_resolution(resolution: float | None, pitch_m: tuple[float, float]) -> float:
    """The nav2 map's metres per pixel: ``resolution`` checked (finite, > 0), or a tenth of the
    smaller pitch. Raises InputError naming ``--nav2-resolution``."""
    if resolution is None:
        return min(pitch_m) / 10.0
    try:
        res = float(resolution)
    except (TypeError, ValueError):
        raise InputError(f"nav2 resolution (--nav2-resolution): expected metres per pixel, "
                         f"got {resolution!r}") from None
    if not (math.isfinite(res) and res > 0):
        raise InputError(f"nav2 resolution (--nav2-resolution): must be a positive number of metres per pixel, "
                         f"got {resolution!r}")
    return res


def nav2_map(detection: Detection, *, resolution: float | None = None) -> tuple[np.ndarray, dict]:
    """A ROS 2 nav2 ``map_server`` map of the floor: (image (H, W) uint8, yaml fields).

    Occupied cells are drawn as the exact squares they are on the floor (the grid is regular in the
    world frame). Pixel 0 = occupied, 254 = free; row 0 of the image is the top (largest y), as
    map_server expects; ``origin`` is the world pose of the bottom-left pixel's corner.

    Raises
    ------
    InputError
        ``resolution`` is not a positive finite number.
    LimitError
        The map would have more pixels than the ``map_pixels`` limit (:mod:`sbplan.limits`).
    """
    cal = detection.calibration
    xmin, ymin, xmax, ymax = cal.world_bounds()
    res = nav2_resolution(resolution, cal.workspace.pitch_m)
    fw, fh = np.ceil((xmax - xmin) / res - 1e-9), np.ceil((ymax - ymin) / res - 1e-9)
    limits.check("map_pixels", float(fw) * float(fh),
                 f"a nav2 map of {fw:.0f} x {fh:.0f} pixels at {res:g} m per pixel", "give a coarser --nav2-resolution")
    width, height = int(fw), int(fh)
    image = np.full((height, width), 254, np.uint8)
    for r, c in detection.occupied_cells:
        lat = np.array([[c - 0.5, r - 0.5], [c + 0.5, r + 0.5]])
        w = cal.workspace.lattice_to_world(lat, cal.grid.rows)
        x0, x1 = sorted(w[:, 0])
        y0, y1 = sorted(w[:, 1])
        c0, c1 = int(round((x0 - xmin) / res)), int(round((x1 - xmin) / res))
        # row flip: image row 0 is the top edge y = ymin + height * res
        r0, r1 = int(round(height - (y1 - ymin) / res)), int(round(height - (y0 - ymin) / res))
        image[max(r0, 0):min(r1, height), max(c0, 0):min(c1, width)] = 0
    meta = {"image": "map.pgm", "mode": "trinary", "resolution": float(res),
            "origin": [float(xmin), float(ymin), 0.0], "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.25}
    return image, meta


def nav2_files(detection: Detection, *, resolution: float | None = None) -> dict[str, bytes | str]:
    """The nav2 map's files, ``{"map.yaml": text, "map.pgm": bytes}`` (see :func:`nav2_map`)."""
    image, meta = nav2_map(detection, resolution=resolution)
    return {"map.yaml": nav2_yaml(meta), meta["image"]: encode_image(meta["image"], image)}


def nav2_yaml(meta: dict) -> str:
    """The text of ``map.yaml`` for :func:`nav2_map`'s fields."""
    lines = [f"image: {meta['image']}", f"mode: {meta['mode']}", f"resolution: {meta['resolution']:.6g}",
             "origin: [{:.6g}, {:.6g}, {:.6g}]".format(*meta["origin"]), f"negate: {meta['negate']}",
             f"occupied_thresh: {meta['occupied_thresh']}", f"free_thresh: {meta['free_thresh']}"]
    return "\n".join(lines) + "\n"


def write_nav2(folder: str | os.PathLike, detection: Detection, *, resolution: float | None = None) -> Path:
    """Write ``map.yaml`` and ``map.pgm`` into ``folder`` as one unit (:func:`sbplan.files.write_file_set`:
    a reader sees the old pair or the new one, never a mix); returns the YAML's path.

    ``folder`` may hold only those two files: sbplan replaces the whole folder."""
    folder = write_file_set(folder, nav2_files(detection, resolution=resolution), names=NAV2_FILES)
    return folder / "map.yaml"
