"""The ArUco layout: one OpenCV ArUco marker at each grid point instead of the symbol.

This is the floor a user would print for the usual alternative to sbplan (a marker grid, where a
marker the detector no longer finds marks its cell occupied). Same grid, obstacles, lighting,
camera and ground-truth rule as the symbol layout, so every method sees the same scene.

Marker of cell ``(row, col)``: id ``row * cols + col`` of the smallest 4x4 dictionary holding
``rows * cols`` ids (:func:`marker_dictionary`); its black-bordered square (6 x 6 modules: 4 x 4
data bits plus the one-module black border) has side ``floor.symbol_size`` and is centred on the grid
point, rotated by ``floor.symbol_angle``. A quiet zone of one module of bare floor (the floor is the
lightest thing printed; no other ink may enter it) surrounds it. The footprint ground truth
measures occlusion against is the marker's square.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np
import shapely
from shapely.geometry import box

from ..errors import SceneError
from .floor import FloorSpec
from .obstacles import coverage, window

#: (dictionary name, number of ids), smallest first: a smaller dictionary has a larger minimum
#: Hamming distance between codes, so fewer misread ids.
DICTIONARIES = (("DICT_4X4_50", 50), ("DICT_4X4_100", 100), ("DICT_4X4_250", 250), ("DICT_4X4_1000", 1000))
#: Modules across a marker: 4 data bits plus one border module on each side.
MODULES = 6
#: Quiet zone (bare floor) around the black square, in modules.
QUIET_MODULES = 1


def marker_dictionary(n_markers: int) -> tuple[str, "cv2.aruco.Dictionary"]:
    """The smallest 4x4 ArUco dictionary with at least ``n_markers`` ids, and its name.

    Raises
    ------
    SceneError
        More than 1000 markers (the largest 4x4 dictionary).
    """
    for name, size in DICTIONARIES:
        if n_markers <= size:
            return name, cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
    raise SceneError(f"cols/rows: an ArUco floor holds at most {DICTIONARIES[-1][1]} markers, got {n_markers}")


@functools.lru_cache(maxsize=None)
def _marker_polygons(dictionary_name: str, marker_id: int) -> tuple:
    """Black parts of one marker in a unit square centred on the origin, as shapely geometry."""
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary_name))
    bits = cv2.aruco.generateImageMarker(d, marker_id, MODULES, borderBits=1) == 0  # (row, col), True = black
    rows, cols = np.nonzero(bits)
    u = 1.0 / MODULES
    cells = [box(-0.5 + c * u, -0.5 + r * u, -0.5 + (c + 1) * u, -0.5 + (r + 1) * u) for r, c in zip(rows, cols)]
    merged = shapely.union_all(cells)
    geoms = getattr(merged, "geoms", [merged])
    return tuple([np.asarray(g.exterior.coords)[:-1], *(np.asarray(h.coords)[:-1] for h in g.interiors)]
                 for g in geoms)


def aruco_pattern(floor: FloorSpec) -> tuple[np.ndarray, list[list[np.ndarray]]]:
    """Ink coverage of the marker grid, and each cell's footprint (the marker's square).

    Returns
    -------
    alpha : ndarray (H, W) float32 in [0, 1]
        Ink coverage in the floor plane.
    footprints : list of list of ndarray
        Per cell in row-major order (``row * cols + col``): ``[square]``, the marker's outer
        square ``(4, 2)`` in floor pixels ``(x, y)``.

    Raises
    ------
    SceneError
        The markers with their quiet zones overlap each other or leave the image, or the grid
        has more cells than the largest dictionary has ids.
    """
    name, _ = marker_dictionary(floor.rows * floor.cols)
    side = float(floor.symbol_size)
    a = math.radians(floor.symbol_angle)
    # counter-clockwise as displayed, as the symbols turn (y down)
    rot = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
    # half extent along x and y of the rotated square with its quiet zone
    half = 0.5 * side * (MODULES + 2 * QUIET_MODULES) / MODULES * (abs(math.cos(a)) + abs(math.sin(a)))
    dx = float(np.min(np.diff(floor.col_x))) if floor.cols > 1 else math.inf
    dy = float(np.min(np.diff(floor.row_y))) if floor.rows > 1 else math.inf
    if 2 * half > min(dx, dy):
        raise SceneError(f"symbol_size: {side:.3g} px ArUco markers with their quiet zone overlap their "
                         f"neighbours at pitch ({dx:.3g}, {dy:.3g}) px")
    if (floor.col_x[0] - half < 0 or floor.col_x[-1] + half > floor.width or floor.row_y[0] - half < 0
            or floor.row_y[-1] + half > floor.height):
        raise SceneError(f"symbol_size: {side:.3g} px ArUco markers with their quiet zone leave the "
                         f"{floor.width} x {floor.height} image")
    square = np.array([[-0.5, -0.5], [-0.5, 0.5], [0.5, 0.5], [0.5, -0.5]]) * side @ rot.T
    alpha = np.zeros((floor.height, floor.width), np.float32)
    footprints = []
    for r, y in enumerate(floor.row_y):
        for c, x in enumerate(floor.col_x):
            centre = np.array([x, y])
            footprints.append([square + centre])
            polys = [[ring * side @ rot.T + centre for ring in rings]
                     for rings in _marker_polygons(name, r * floor.cols + c)]
            win = window(footprints[-1][0], floor.width, floor.height)
            if win is None:
                continue
            x0, y0, w, h = win
            np.maximum(alpha[y0:y0 + h, x0:x0 + w], coverage(polys, x0, y0, w, h),
                       out=alpha[y0:y0 + h, x0:x0 + w])
    return alpha, footprints
