"""Labelled silhouette sets for shape-retrieval benchmarks, and reading them back.

A set is a folder of PNG files named ``<class>-<n>.png``: a white shape on black or a black shape
on white. :func:`make_silhouettes` generates one from parametric shapes (random star-shaped
polygons, stars, letter-like stroke shapes, smooth blobs); every instance of a class is its base
shape under a random rotation, scale, shear and small vertex jitter, rasterized with OpenCV.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..errors import ImageError, InputError
from ..imageio import load_image, write_image

__all__ = ["make_silhouettes", "load_silhouettes", "largest_outline", "Silhouettes", "FAMILIES"]

FAMILIES = ("polygon", "star", "letter", "blob")

#: Letter-like stroke skeletons on a unit box (y down); each is a list of polylines.
_LETTERS = {
    "L": [[(0, 0), (0, 1), (0.7, 1)]],
    "T": [[(0, 0), (1, 0)], [(0.5, 0), (0.5, 1)]],
    "E": [[(0.8, 0), (0, 0), (0, 1), (0.8, 1)], [(0, 0.5), (0.6, 0.5)]],
    "F": [[(0.8, 0), (0, 0), (0, 1)], [(0, 0.5), (0.6, 0.5)]],
    "H": [[(0, 0), (0, 1)], [(0.8, 0), (0.8, 1)], [(0, 0.5), (0.8, 0.5)]],
    "U": [[(0, 0), (0, 1), (0.8, 1), (0.8, 0)]],
    "Z": [[(0, 0), (0.8, 0), (0, 1), (0.8, 1)]],
    "Y": [[(0, 0), (0.4, 0.5), (0.8, 0)], [(0.4, 0.5), (0.4, 1)]],
    "K": [[(0, 0), (0, 1)], [(0.8, 0), (0, 0.55), (0.8, 1)]],
    "X": [[(0, 0), (0.8, 1)], [(0.8, 0), (0, 1)]],
    "V": [[(0, 0), (0.4, 1), (0.8, 0)]],
    "N": [[(0, 1), (0, 0), (0.8, 1), (0.8, 0)]],
}


@dataclass(frozen=True)
class _ClassSpec:
    name: str
    family: str
    params: dict


def _class_specs(classes: int, rng: np.random.Generator) -> list[_ClassSpec]:
    letters = list(_LETTERS)
    rng.shuffle(letters)
    specs = []
    for i in range(classes):
        family = FAMILIES[i % len(FAMILIES)]
        name = f"{family}{i:02d}"
        if family == "polygon":
            n = int(rng.integers(5, 10))
            t = np.sort(rng.uniform(0, 2 * np.pi, n))
            params = {"angles": t, "radii": rng.uniform(0.45, 1.0, n)}
        elif family == "star":
            params = {"points": int(rng.integers(4, 9)), "inner": float(rng.uniform(0.35, 0.7))}
        elif family == "letter":
            params = {"letter": letters[(i // len(FAMILIES)) % len(letters)],
                      "thickness": float(rng.uniform(0.14, 0.24))}
        else:
            k = np.arange(2, 6)
            params = {"amp": rng.uniform(0.0, 0.18, len(k)) / (k - 1) ** 0.5, "phase": rng.uniform(0, 2 * np.pi, len(k)), "k": k}
        specs.append(_ClassSpec(name, family, params))
    return specs


def _base_outline(spec: _ClassSpec) -> np.ndarray | None:
    """The class's outline (N, 2) centred on (0, 0) with radius about 1, or None for letters."""
    p = spec.params
    if spec.family == "polygon":
        return np.c_[p["radii"] * np.cos(p["angles"]), p["radii"] * np.sin(p["angles"])]
    if spec.family == "star":
        n = p["points"]
        t = np.arange(2 * n) * np.pi / n
        r = np.where(np.arange(2 * n) % 2 == 0, 1.0, p["inner"])
        return np.c_[r * np.cos(t), r * np.sin(t)]
    if spec.family == "blob":
        t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
        r = 0.8 + (p["amp"][:, None] * np.cos(p["k"][:, None] * t + p["phase"][:, None])).sum(axis=0)
        return np.c_[r * np.cos(t), r * np.sin(t)]
    return None


def _render(spec: _ClassSpec, size: int, rng: np.random.Generator) -> np.ndarray:
    """One random instance of a class as a binary uint8 image (255 = shape)."""
    angle = rng.uniform(0, 2 * np.pi)
    scale = size * rng.uniform(0.28, 0.42)
    shear = rng.uniform(-0.08, 0.08)
    stretch = rng.uniform(0.92, 1.08)
    c, s = np.cos(angle), np.sin(angle)
    affine = np.array([[c, -s], [s, c]]) @ np.array([[stretch, shear], [0.0, 1.0 / stretch]]) * scale
    centre = size / 2 + rng.uniform(-0.04, 0.04, 2) * size
    img = np.zeros((size, size), np.uint8)
    outline = _base_outline(spec)
    if outline is not None:
        jitter = rng.normal(0, 0.02, outline.shape)  # small non-rigid perturbation
        pts = (outline + jitter) @ affine.T + centre
        cv2.fillPoly(img, [np.round(pts * 16).astype(np.int32)], 255, lineType=cv2.LINE_8, shift=4)
        return img
    strokes = _LETTERS[spec.params["letter"]]
    thick = max(2, int(round(spec.params["thickness"] * scale * 1.6)))
    for line in strokes:
        q = np.asarray(line, float) - (0.4, 0.5)
        q = (q + rng.normal(0, 0.02, q.shape)) * 1.6 @ affine.T + centre
        cv2.polylines(img, [np.round(q * 16).astype(np.int32)], False, 255, thick, cv2.LINE_8, shift=4)
    return img


def make_silhouettes(folder, *, classes: int = 12, per_class: int = 10, seed: int = 0,
                     size: int = 128) -> list[Path]:
    """Write a labelled silhouette set ``<class>-<n>.png`` into ``folder``.

    Parameters
    ----------
    folder : path
        Created if missing; existing files of the same names are replaced.
    classes, per_class : int
        Number of classes (>= 2) and of instances per class (>= 2).
    seed : int
        Seeds every random choice: the same arguments give the same images.
    size : int
        Image width and height in pixels (>= 32).

    Returns
    -------
    list of Path
        The files written, class by class.
    """
    for key, value, low in (("classes", classes, 2), ("per_class", per_class, 2), ("size", size, 32)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise InputError(f"{key} must be an integer >= {low}, got {value!r}")
    rng = np.random.default_rng(seed)
    specs = _class_specs(int(classes), rng)
    folder = Path(folder)
    written = []
    for spec in specs:
        for n in range(int(per_class)):
            img = _render(spec, int(size), rng)
            if rng.random() < 0.5:  # both polarities, as the reader must accept
                img = 255 - img
            written.append(write_image(folder / f"{spec.name}-{n}.png", img))
    return written


_NAME = re.compile(r"^(?P<cls>.+)-(?P<n>\d+)$")


@dataclass(frozen=True)
class Silhouettes:
    """A loaded silhouette set: per file its path, class label and largest outer outline."""

    paths: list[Path]
    labels: list[str]
    outlines: list[np.ndarray]


def largest_outline(gray: np.ndarray, *, name: str = "image") -> np.ndarray:
    """The largest outer contour (N, 2) int64 ``(x, y)`` of the shape in a silhouette image.

    The shape is whichever polarity does not touch most of the image border: a white shape on black
    or a black shape on white.
    """
    binary = gray >= 128
    border = np.concatenate([binary[0], binary[-1], binary[:, 0], binary[:, -1]])
    if border.mean() > 0.5:
        binary = ~binary
    found, _ = cv2.findContours(binary.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    found = [c for c in found if len(c) >= 3]
    if not found:
        raise ImageError(f"{name}: no shape found (blank image)")
    best = max(found, key=lambda c: (cv2.contourArea(c), len(c)))
    return best[:, 0].astype(np.int64)


def load_silhouettes(folder) -> Silhouettes:
    """Read every ``<class>-<n>.png`` of a folder (sorted by name).

    Raises
    ------
    InputError
        The folder is missing or not a folder, holds no PNG, or a PNG's name has no class.
    ImageError
        A PNG cannot be read or shows no shape.
    """
    folder = Path(folder)
    if not folder.exists():
        raise InputError(f"{folder}: no such folder")
    if not folder.is_dir():
        raise InputError(f"{folder}: not a folder")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".png" and p.is_file())
    if not files:
        raise InputError(f"{folder}: no PNG files named <class>-<n>.png")
    labels = []
    for p in files:
        match = _NAME.match(p.stem)
        if not match:
            raise InputError(f"{p}: file name has no class; expected <class>-<n>.png, e.g. star-3.png")
        labels.append(match["cls"])
    outlines = [largest_outline(load_image(p), name=str(p)) for p in files]
    return Silhouettes(files, labels, outlines)
