"""Labelled silhouette sets for shape-retrieval benchmarks, and reading them back.

A set is a folder of PNG files named ``<class>-<n>.png``: a white shape on black or a black shape
on white. :func:`make_silhouettes` generates one from parametric shapes (random star-shaped
polygons, stars, letter-like stroke shapes, smooth blobs, animals with bending limbs, and near
copies of earlier classes); every instance of a class is its base shape under a random rotation,
scale, shear, small vertex jitter and, now and then, a mirror flip, rasterized with OpenCV, and
then given the hard cases of MPEG-7 CE-Shape-1: limbs bent at their joints, a part cut away
(occlusion), a ragged boundary, holes.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..errors import ImageError, InputError
from ..imageio import load_image, write_image

__all__ = ["make_silhouettes", "load_silhouettes", "largest_outline", "Silhouettes", "FAMILIES"]

FAMILIES = ("polygon", "star", "letter", "blob", "animal", "sibling")

#: How often an instance gets each hard case (independently), and how strong it is.
HARD_CASES = {
    "mirror": 0.25,     # flipped left to right, as MPEG-7's classes mix facing directions
    "occlusion": 0.25,  # a disc of 0.35-0.6 radii centred near the boundary cut away
    "ragged": 0.3,      # 6-14 small discs added or removed along the boundary
    "holes": 0.3,       # 1-3 holes punched inside (the outer contour is what is matched)
}

#: Letter-like stroke skeletons on a unit box (y down); each is a list of polylines.
_LETTERS: dict[str, list[list[tuple[float, float]]]] = {
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
    params: dict[str, Any]


def _class_specs(classes: int, rng: np.random.Generator) -> list[_ClassSpec]:
    letters = list(_LETTERS)
    rng.shuffle(letters)
    specs: list[_ClassSpec] = []
    for i in range(classes):
        family = FAMILIES[i % len(FAMILIES)]
        name = f"{family}{i:02d}"
        params: dict[str, Any]  # per family: arrays, numbers, a letter, or the base class's spec
        if family == "polygon":
            n = int(rng.integers(5, 10))
            t = np.sort(rng.uniform(0, 2 * np.pi, n))
            params = {"angles": t, "radii": rng.uniform(0.45, 1.0, n)}
        elif family == "star":
            params = {"points": int(rng.integers(4, 9)), "inner": float(rng.uniform(0.35, 0.7))}
        elif family == "letter":
            params = {"letter": letters[(i // len(FAMILIES)) % len(letters)],
                      "thickness": float(rng.uniform(0.14, 0.24))}
        elif family == "blob":
            k = np.arange(2, 6)
            params = {"amp": rng.uniform(0.0, 0.18, len(k)) / (k - 1) ** 0.5, "phase": rng.uniform(0, 2 * np.pi, len(k)), "k": k}
        elif family == "animal":
            limbs = int(rng.integers(2, 6))
            params = {"aspect": float(rng.uniform(0.35, 0.7)),
                      "anchors": np.sort(rng.uniform(0, 2 * np.pi, limbs)),
                      "lengths": rng.uniform(0.3, 0.6, (limbs, 2)),
                      "bends": rng.uniform(-0.6, 0.6, limbs),
                      "thickness": float(rng.uniform(0.12, 0.2))}
        else:  # a near copy of an earlier class: the MPEG-7 case of two classes that look alike
            bases = [sp for sp in specs if sp.family != "sibling"]
            base = bases[int(rng.integers(0, len(bases)))]
            params = {"base": base, "bump_at": float(rng.uniform(0, 2 * np.pi)), "bump": float(rng.uniform(0.25, 0.4))}
        specs.append(_ClassSpec(name, family, params))
    return specs


def _base_outline(spec: _ClassSpec) -> np.ndarray | None:
    """The class's outline (N, 2) centred on (0, 0) with radius about 1, or None for letters and
    animals (drawn as strokes)."""
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


def _strokes(spec: _ClassSpec, rng: np.random.Generator) -> tuple[list[np.ndarray], float, np.ndarray | None]:
    """The class's strokes for one instance: polylines (N_i, 2) centred on (0, 0) with radius
    about 1 (y down), their thickness in the same unit, and a filled body outline or None.
    Animals' limbs bend at both joints by up to +-35 degrees from one instance to the next."""
    p = spec.params
    if spec.family == "letter":
        lines = [(np.asarray(line, float) - (0.4, 0.5) + rng.normal(0, 0.02, (len(line), 2))) * 1.6
                 for line in _LETTERS[p["letter"]]]
        return lines, p["thickness"] * 1.6, None
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    a, b = 0.55, 0.55 * p["aspect"]
    body = np.c_[a * np.cos(t), b * np.sin(t)] + rng.normal(0, 0.01, (len(t), 2))
    lines = []
    for ang, (l1, l2), bend in zip(p["anchors"], p["lengths"], p["bends"]):
        root = 0.8 * np.array([a * np.cos(ang), b * np.sin(ang)])
        d1 = ang + rng.uniform(-0.6, 0.6)
        knee = root + 0.6 * l1 * np.array([np.cos(d1), np.sin(d1)])
        d2 = d1 + bend + rng.uniform(-0.6, 0.6)
        foot = knee + 0.6 * l2 * np.array([np.cos(d2), np.sin(d2)])
        lines.append(np.array([root, knee, foot]) * 0.85)
    return lines, p["thickness"] * 0.85, body * 0.85


def _render(spec: _ClassSpec, size: int, rng: np.random.Generator) -> np.ndarray:
    """One random instance of a class as a binary uint8 image (255 = shape), hard cases included."""
    if spec.family == "sibling":
        img = _render_sibling(spec, size, rng)
    else:
        img = _render_plain(spec, size, rng)
    return _hard_cases(img, size, rng)


def _render_sibling(spec: _ClassSpec, size: int, rng: np.random.Generator) -> np.ndarray:
    """The base class's instance with a bump grown at a fixed place of its outline: the two
    classes differ in that one part only."""
    p = spec.params
    base = p["base"]
    # the bump is placed in the base's own frame, before the instance's rotation and scale
    return _render_plain(base, size, rng, bump=(p["bump_at"], p["bump"]))


def _render_plain(spec: _ClassSpec, size: int, rng: np.random.Generator, *,
                  bump: tuple[float, float] | None = None) -> np.ndarray:
    """One instance of a class before the hard cases: rotation, scale, shear, stretch, jitter."""
    angle = rng.uniform(0, 2 * np.pi)
    scale = size * rng.uniform(0.28, 0.42)
    shear = rng.uniform(-0.08, 0.08)
    stretch = rng.uniform(0.92, 1.08)
    c, s = np.cos(angle), np.sin(angle)
    affine = np.array([[c, -s], [s, c]]) @ np.array([[stretch, shear], [0.0, 1.0 / stretch]]) * scale
    centre = size / 2 + rng.uniform(-0.04, 0.04, 2) * size
    if rng.random() < HARD_CASES["mirror"]:
        affine = affine @ np.diag([-1.0, 1.0])
    img = np.zeros((size, size), np.uint8)
    outline = _base_outline(spec)
    if outline is not None:
        jitter = rng.normal(0, 0.02, outline.shape)  # small non-rigid perturbation
        pts = (outline + jitter) @ affine.T + centre
        cv2.fillPoly(img, [np.round(pts * 16).astype(np.int32)], 255, lineType=cv2.LINE_8, shift=4)
    else:
        lines, thickness, body = _strokes(spec, rng)
        thick = max(2, int(round(thickness * scale)))
        if body is not None:
            q = body @ affine.T + centre
            cv2.fillPoly(img, [np.round(q * 16).astype(np.int32)], 255, lineType=cv2.LINE_8, shift=4)
        for line in lines:
            q = line @ affine.T + centre
            cv2.polylines(img, [np.round(q * 16).astype(np.int32)], False, 255, thick, cv2.LINE_8, shift=4)
    if bump is not None:
        at, radius = bump
        # centred on the shape's farthest pixel in the direction `at` of the base shape's frame,
        # so it sits at the same place of every instance and always joins the shape
        ys, xs = np.nonzero(img)
        if len(xs):
            k = int(np.argmax((np.c_[xs, ys] - centre) @ (affine @ np.array([np.cos(at), np.sin(at)]))))
            cv2.circle(img, (int(xs[k]), int(ys[k])), max(2, int(round(radius * scale * 0.5))), 255, -1)
    return img


def _hard_cases(img: np.ndarray, size: int, rng: np.random.Generator) -> np.ndarray:
    """Occlusion, a ragged boundary and holes (see :data:`HARD_CASES`), each drawn at random."""
    area = int(np.count_nonzero(img))
    if area == 0:
        return img
    radius = float(np.sqrt(area / np.pi))  # of the disc of the shape's area
    edge = np.argwhere(cv2.morphologyEx(img, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0)[:, ::-1]
    if rng.random() < HARD_CASES["occlusion"] and len(edge):
        at = edge[int(rng.integers(len(edge)))]
        cut = img.copy()
        cv2.circle(cut, (int(at[0]), int(at[1])), int(round(rng.uniform(0.35, 0.6) * radius)), 0, -1)
        if cut.sum() > 0.6 * img.sum():  # keep most of the shape: occluded, not replaced
            img = cut
    if rng.random() < HARD_CASES["ragged"] and len(edge):
        for _ in range(int(rng.integers(6, 15))):
            at = edge[int(rng.integers(len(edge)))]
            r = max(1, int(round(rng.uniform(0.03, 0.08) * radius)))
            cv2.circle(img, (int(at[0]), int(at[1])), r, int(255 * (rng.random() < 0.5)), -1)
    if rng.random() < HARD_CASES["holes"]:
        inner = cv2.erode(img, np.ones((5, 5), np.uint8), iterations=max(1, int(radius * 0.15)))
        spots = np.argwhere(inner > 0)[:, ::-1]
        for _ in range(int(rng.integers(1, 4)) if len(spots) else 0):
            at = spots[int(rng.integers(len(spots)))]
            cv2.circle(img, (int(at[0]), int(at[1])), max(1, int(round(rng.uniform(0.05, 0.12) * radius))), 0, -1)
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
