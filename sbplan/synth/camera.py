"""The fixed ceiling camera: perspective tilt and radial lens distortion.

The floor plane is measured in pixels so that an untilted, undistorted camera shows it 1:1. A tilt
is a rotation of the camera about its centre (focal length = image width), composed with a shift
that keeps the floor's centre at the image centre. Distortion is radial about the image centre on
coordinates normalized by the half diagonal: an image point ``d`` shows the ideal point
``d * (1 + k1 |d|^2)`` (k1 > 0: barrel).
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from ..polygons import apply_homography


@functools.lru_cache(maxsize=16)
def _homography(width: int, height: int, tilt: tuple[float, float]) -> np.ndarray:
    f = float(width)
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    k = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]])
    ax, ay = (math.radians(t) for t in tilt)
    rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    h = k @ rx @ ry @ np.linalg.inv(k)
    c = h @ np.array([cx, cy, 1.0])
    shift = np.array([[1, 0, cx - c[0] / c[2]], [0, 1, cy - c[1] / c[2]], [0, 0, 1.0]])
    h = shift @ h
    return h / h[2, 2]


class Camera:
    """Maps floor-plane pixels to image pixels and back.

    Parameters
    ----------
    width, height : int
        Image size.
    tilt : (float, float)
        Degrees about the x and y axes.
    distortion : float
        Radial k1 (see module doc).
    """

    def __init__(self, width: int, height: int, tilt=(0.0, 0.0), distortion: float = 0.0):
        self.width, self.height = int(width), int(height)
        self.tilt = (float(tilt[0]), float(tilt[1]))
        self.distortion = float(distortion)
        self.h = _homography(self.width, self.height, self.tilt)
        self.h_inv = np.linalg.inv(self.h)
        self.centre = np.array([(self.width - 1) / 2.0, (self.height - 1) / 2.0])
        self.radius = 0.5 * math.hypot(self.width, self.height)

    @property
    def identity(self) -> bool:
        return self.tilt == (0.0, 0.0) and self.distortion == 0.0

    def floor_to_image(self, pts: np.ndarray) -> np.ndarray:
        """Image points ``(..., 2)`` ``(x, y)`` of floor points ``(..., 2)``."""
        pts = np.asarray(pts, dtype=np.float64)
        if self.identity:
            return pts.copy()
        q = pts @ self.h[:2, :2].T + self.h[:2, 2]
        w = pts @ self.h[2, :2] + self.h[2, 2]
        u = (q / w[..., None] - self.centre) / self.radius
        if self.distortion:
            # invert u = d (1 + k |d|^2) by fixed-point iteration (converges fast for |k| <= 0.3)
            d = u.copy()
            for _ in range(30):
                d = u / (1.0 + self.distortion * np.sum(d * d, axis=-1, keepdims=True))
            u = d
        return u * self.radius + self.centre

    def image_to_floor(self, pts: np.ndarray) -> np.ndarray:
        """Floor points of image points ``(..., 2)`` ``(x, y)``."""
        pts = np.asarray(pts, dtype=np.float64)
        if self.identity:
            return pts.copy()
        d = (pts - self.centre) / self.radius
        u = d * (1.0 + self.distortion * np.sum(d * d, axis=-1, keepdims=True))
        p = u * self.radius + self.centre
        q = p @ self.h_inv[:2, :2].T + self.h_inv[:2, 2]
        w = p @ self.h_inv[2, :2] + self.h_inv[2, 2]
        return q / w[..., None]

    def warp(self, floor_image: np.ndarray) -> np.ndarray:
        """The camera's view of a floor-plane image of the same size (bilinear)."""
        if self.identity:
            return floor_image
        mx, my = _maps(self.width, self.height, self.tilt, self.distortion)
        return cv2.remap(floor_image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


@functools.lru_cache(maxsize=8)
def _maps(width: int, height: int, tilt: tuple[float, float], distortion: float):
    cam = Camera(width, height, tilt, distortion)
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    f = cam.image_to_floor(np.stack([xs, ys], axis=-1))
    mx, my = f[..., 0].astype(np.float32), f[..., 1].astype(np.float32)
    mx.setflags(write=False)
    my.setflags(write=False)
    return mx, my


def motion_matrix(width: int, height: int, motion) -> np.ndarray:
    """The 3x3 map from the calibrated view's pixels to a moved camera's pixels.

    Parameters
    ----------
    width, height : int
        Image size.
    motion : (dx, dy, rotation_deg, scale)
        A similarity about the image centre ``c``: ``p -> scale * R (p - c) + c + (dx, dy)``, with
        ``R`` a rotation counter-clockwise as displayed (y down).

    Returns
    -------
    ndarray of shape (3, 3), float64, acting on ``(x, y, 1)``.
    """
    dx, dy, rot, scale = (float(v) for v in motion)
    c = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    a = math.radians(rot)
    # counter-clockwise as displayed with y down: x' = x cos + y sin, y' = -x sin + y cos
    lin = scale * np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
    m = np.eye(3)
    m[:2, :2] = lin
    m[:2, 2] = c + (dx, dy) - lin @ c
    return m


def view_change(width: int, height: int, motion=None, sag=None) -> np.ndarray | None:
    """The 3x3 map from the calibrated view's pixels to the pixels of a camera that moved by
    ``motion`` (:func:`motion_matrix`) after it tilted by ``sag`` ``(about_x, about_y)`` degrees
    about the image centre (a perspective change: a homography), or None when neither is given."""
    if motion is None and sag is None:
        return None
    m = motion_matrix(width, height, motion if motion is not None else (0.0, 0.0, 0.0, 1.0))
    if sag is not None:
        m = m @ _homography(int(width), int(height), (float(sag[0]), float(sag[1])))
    return m / m[2, 2]


def moved_view(floor_image: np.ndarray, camera: Camera, matrix: np.ndarray) -> np.ndarray:
    """What ``camera`` moved by ``matrix`` (:func:`motion_matrix`) sees of ``floor_image`` (the
    floor plane, the image's size), in one interpolation: each moved pixel reads the floor point
    the calibrated camera saw there."""
    h, w = floor_image.shape[:2]
    inv = np.linalg.inv(matrix)
    projective = bool(matrix[2, 0] or matrix[2, 1])
    if camera.identity:
        # warpAffine takes the forward map and reads dst(p) = src(matrix^-1 p)
        if projective:
            return cv2.warpPerspective(floor_image, matrix.astype(np.float64), (w, h), flags=cv2.INTER_LINEAR,
                                       borderMode=cv2.BORDER_REFLECT)
        return cv2.warpAffine(floor_image, matrix[:2].astype(np.float64), (w, h), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REFLECT)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    p = apply_homography(inv, np.stack([xs, ys], axis=-1))
    f = camera.image_to_floor(p)
    return cv2.remap(floor_image, f[..., 0].astype(np.float32), f[..., 1].astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REFLECT)
