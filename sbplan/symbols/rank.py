"""Ranking candidate reference symbols: the paper's section 3, measured.

For M candidates the paper computes Fourier descriptors (FDs) and

- equation (2): ``d_ij = sqrt(sum_k (A_ik - A_jk)^2)``, the distance matrix;
- equation (3): the mean ``dbar_i = (1/M) sum_j d_ij`` and the variance
  ``v_i = 1/(M-1) sum_j (d_ij - dbar_i)^2``;
- equation (4): the ranking by ``v_i / dbar_i``, smallest first (far from all others, evenly);
- condition 3: the symbol chosen is the first of that ranking with a *partially regular* outline.

Two decisions the paper leaves open, stated here once:

- **Typo in equation (3).** The paper prints ``(d_ij - dbar_j)^2``; that mixes another row's mean
  into symbol i's spread. sbplan uses ``dbar_i``: ``v_i`` is the sample variance of row i.
- **The diagonal is included.** The sums run over all M columns, ``j = i`` included, as the paper's
  ``1/M sum_{j=1..M}`` says. So ``dbar_i`` and ``v_i`` are the mean and the sample variance
  (``ddof=1``) of the M values of row i, one of which is ``d_ii = 0``. That zero lowers every mean
  by the same factor (M-1)/M and is the same for every row, so it does not reorder the means.

Descriptors come from the camera's view, not the ideal polygon: each candidate is rendered at a
few sizes, rotations and blur levels, binarized, its contour extracted and approximated with the
chosen stages, and described with the chosen matcher. The candidate's descriptor is the
element-wise median over those renderings (as calibration does with the reference's symbols).

sbplan adds two measured scores:

- **Regularity** (condition 3): the share of the outline's length (all rings) that lies in
  straight pieces. Measured on a large rasterization (600 px, at 0 and 17 degrees): the pixel
  contour is approximated by Douglas-Peucker with a 1.2 px tolerance (a digitized straight edge
  stays within about 1 px of its chord), and an edge of that polygon counts as straight when it is
  at least 15 % of the symbol's size long. A circle of 600 px is then cut into chords of about
  54 px (9 %) and the flattest part of a 2:1 ellipse into chords of 13 %, so round outlines score
  0, while an outline of long straight sides scores near 1.
- **Confusion margin**: the distance from the candidate's descriptor to the nearest shape of the
  noise set (:mod:`sbplan.symbols.noise`, rendered the same way) divided by the candidate's own
  *spread*, the largest distance of one of its renderings from its descriptor. Below 1 a noise
  contour is closer than some true views of the symbol: no threshold can separate them.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import cv2
import numpy as np

from .. import registry
from ..contracts import Binarizer, ContourApproximator, ContourExtractor, DescriptorMatcher
from ..errors import InputError
from .noise import NOISE_FAMILIES, noise_set, parse_families
from .raster import coverage, place, symbol_rings

__all__ = [
    "DEFAULT_ANGLES", "DEFAULT_BLURS", "DEFAULT_SIZES", "Ranking", "describe_views", "distance_matrix",
    "distance_statistics", "outline_of", "rank_order", "rank_symbols", "regularity", "render_view",
]

#: The renderings every candidate is seen in: symbol sizes (px), rotations (deg), blur sigmas (px).
DEFAULT_SIZES = (36, 56, 90)
DEFAULT_ANGLES = (0.0, 33.0, 71.0, 152.0)
DEFAULT_BLURS = (0.0, 1.3)

#: Grey levels of the floor and the ink in the rendered views (the renderer's defaults: 185 and 45).
_PAPER, _INK = 185.0, 45.0


# -- equations (2)-(4) ---------------------------------------------------------------------------
def distance_matrix(descriptors: np.ndarray, matcher: str | DescriptorMatcher | None = None) -> np.ndarray:
    """Equation (2): all pairwise distances between the rows of ``descriptors`` (M, K).

    With ``matcher`` None the Euclidean distance of the paper; otherwise the matcher's own
    ``distance_matrix`` (a name or a stage instance). Returns an (M, M) symmetric array, zero
    diagonal.
    """
    a = np.asarray(descriptors, np.float64)
    if a.ndim != 2 or len(a) < 2:
        raise InputError(f"descriptors: expected shape (M, K) with M >= 2, got {a.shape}")
    if not np.isfinite(a).all():
        raise InputError("descriptors: contain NaN or infinite values")
    if matcher is None:
        d = a[:, None, :] - a[None, :, :]
        return np.sqrt(np.einsum("ijk,ijk->ij", d, d))
    m = registry.matcher(matcher) if isinstance(matcher, str) else matcher
    d = np.asarray(m.distance_matrix(a, a), np.float64)
    d = 0.5 * (d + d.T)  # guard against round-off asymmetry of a plugin's distance
    np.fill_diagonal(d, 0.0)
    return d


def distance_statistics(distances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Equation (3): per symbol the mean distance and the variance of the distances.

    Parameters
    ----------
    distances : ndarray of shape (M, M)
        The distance matrix of equation (2), M >= 2.

    Returns
    -------
    mean : ndarray of shape (M,)
        ``dbar_i = (1/M) sum_j d_ij``, the diagonal ``d_ii = 0`` included.
    variance : ndarray of shape (M,)
        ``v_i = 1/(M-1) sum_j (d_ij - dbar_i)^2`` (the paper's ``dbar_j`` is a typo).
    """
    d = np.asarray(distances, np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1] or d.shape[0] < 2:
        raise InputError(f"distances: expected a square (M, M) matrix with M >= 2, got {d.shape}")
    if not np.isfinite(d).all() or (d < 0).any():
        raise InputError("distances: must be finite and >= 0")
    mean = d.mean(axis=1)
    variance = ((d - mean[:, None]) ** 2).sum(axis=1) / (d.shape[0] - 1)
    return mean, variance


def rank_order(distances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Equation (4): the score ``v_i / dbar_i`` and the indices sorted by it, smallest first.

    A symbol at distance 0 from every other (``dbar_i = 0``) gets an infinite score. Ties keep
    the input order.
    """
    mean, var = distance_statistics(distances)
    with np.errstate(divide="ignore", invalid="ignore"):
        score = np.where(mean > 0, var / np.where(mean > 0, mean, 1.0), np.inf)
    return score, np.argsort(score, kind="stable")


# -- the camera's view of one shape --------------------------------------------------------------
def render_view(rings: Sequence[np.ndarray], *, size: float, angle: float = 0.0, blur: float = 0.0,
                noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """One shape on an empty patch of floor as the fixed camera sees it.

    Parameters
    ----------
    rings : list of ndarray (N, 2)
        ``[outline, *holes]`` in a unit box, ``(x, y)``, y down.
    size : float
        Side of the unit box in pixels.
    angle : float
        Rotation in degrees, counter-clockwise as displayed, about the centre of area.
    blur : float
        Gaussian blur sigma in pixels (defocus).
    noise : float
        Standard deviation of additive sensor noise in grey levels.
    seed : int
        Seed of the noise.

    Returns
    -------
    ndarray of shape (H, W), uint8
        Dark ink (45) on a light floor (185), the shape with a margin of a quarter of its size
        (at least 6 px) on every side.
    """
    pad = max(6, int(math.ceil(0.25 * size + 3 * blur)))
    placed = place(rings, size=size, angle=angle)
    pts = np.vstack(placed)
    lo = np.floor(pts.min(axis=0)) - pad
    hi = np.ceil(pts.max(axis=0)) + pad
    placed = [r - lo for r in placed]
    w, h = (hi - lo + 1).astype(int)
    alpha = coverage(placed, (h, w), supersample=8)
    img: np.ndarray = _PAPER - (_PAPER - _INK) * alpha
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), float(blur))
    if noise > 0:
        img = img + np.random.default_rng(seed).standard_normal(img.shape).astype(np.float32) * noise
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def outline_of(gray: np.ndarray, *, binarizer: Binarizer, extractor: ContourExtractor,
               approximator: ContourApproximator) -> np.ndarray | None:
    """The approximated polygon ``(M, 2)`` ``(x, y)`` of the largest outer contour of an image of
    one shape, or None when the stages find no polygon."""
    binary = binarizer.binarize(gray)
    best, best_area = None, 0.0
    for c in extractor.extract(binary):
        if c.is_hole or len(c.points) < 8:
            continue
        area = abs(cv2.contourArea(c.points.astype(np.float32).reshape(-1, 1, 2)))
        if area > best_area:
            best, best_area = c, area
    if best is None:
        return None
    poly = approximator.approximate(best)
    return poly if len(poly) >= 3 else None


def _stages(binarizer: str | Binarizer, extractor: str | ContourExtractor, approximator: str | ContourApproximator,
            matcher: str | DescriptorMatcher) -> dict[str, Any]:
    reg = registry.registry()
    return {kind: reg.create(kind, given) for kind, given in
            (("binarizer", binarizer), ("extractor", extractor), ("approximator", approximator),
             ("matcher", matcher))}


def describe_views(rings: Sequence[np.ndarray], *, sizes: Sequence[float] = DEFAULT_SIZES,
                   angles: Sequence[float] = DEFAULT_ANGLES, blurs: Sequence[float] = DEFAULT_BLURS,
                   binarizer: str | Binarizer = "otsu", extractor: str | ContourExtractor = "opencv",
                   approximator: str | ContourApproximator = "douglas-peucker",
                   matcher: str | DescriptorMatcher = "fourier") -> np.ndarray:
    """Descriptors of one shape seen at every combination of size, rotation and blur.

    Returns an array of shape (V, K), one row per rendering in which the stages found the shape
    (V <= len(sizes) * len(angles) * len(blurs)). Stages are names or instances.
    """
    st = _stages(binarizer, extractor, approximator, matcher)
    polys = []
    for size in sizes:
        for angle in angles:
            for blur in blurs:
                p = outline_of(render_view(rings, size=size, angle=angle, blur=blur), binarizer=st["binarizer"],
                               extractor=st["extractor"], approximator=st["approximator"])
                if p is not None:
                    polys.append(p)
    return st["matcher"].describe_many(polys)


# -- condition 3: regularity ---------------------------------------------------------------------
def regularity(rings: Sequence[np.ndarray], *, size: float = 600.0, tolerance: float = 1.2,
               min_piece: float = 0.15, angles: Sequence[float] = (0.0, 17.0)) -> float:
    """Share of the outline's length lying in straight pieces, in [0, 1] (condition 3).

    The shape is rendered at ``size`` pixels (each angle in ``angles``), every contour (outline and
    holes) is approximated by Douglas-Peucker with ``tolerance`` pixels, and the polygon edges at
    least ``min_piece * size`` long count as straight. The result is their total length over the
    polygons' total perimeter, averaged over the angles.
    """
    if not (size >= 50):
        raise InputError(f"size: the regularity rendering needs at least 50 px, got {size!r}")
    if not (0 < tolerance < 0.05 * size):
        raise InputError(f"tolerance: expected 0 < tolerance < size/20 pixels, got {tolerance!r}")
    if not (0 < min_piece < 1):
        raise InputError(f"min_piece: expected a fraction in (0, 1), got {min_piece!r}")
    shares = []
    for angle in angles:
        # Pixel centres inside the polygon: what a sharp image thresholded halfway gives, without
        # the cost of antialiasing a large image.
        half = int(math.ceil(size * 0.75)) + 4
        placed = place(rings, size=size, angle=angle, centre=(half, half))
        binary = (coverage(placed, (2 * half + 1, 2 * half + 1), supersample=1) > 0.5).astype(np.uint8)
        found, _ = cv2.findContours(binary, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
        straight = total = 0.0
        for c in found:
            if len(c) < 0.05 * size:
                continue
            poly = cv2.approxPolyDP(c.astype(np.float32), tolerance, True).reshape(-1, 2)
            edges = np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1)
            total += edges.sum()
            straight += edges[edges >= min_piece * size].sum()
        shares.append(straight / total if total > 0 else 0.0)
    return float(np.mean(shares))


# -- the ranking ---------------------------------------------------------------------------------
@dataclass(eq=False)
class Ranking:
    """The result of :func:`rank_symbols`. Arrays are indexed like ``names`` (input order).

    Attributes
    ----------
    names : list of str
    descriptors : ndarray (M, K)
        Each candidate's descriptor (median over its renderings).
    distances : ndarray (M, M)
        Equation (2).
    mean, variance, score : ndarray (M,)
        Equation (3) and the equation (4) score ``variance / mean``.
    order : ndarray (M,)
        Indices sorted by ``score``, best first.
    regularity : ndarray (M,)
        Share of the outline in straight pieces (see :func:`regularity`).
    spread : ndarray (M,)
        Largest distance of a rendering of the candidate from its descriptor.
    noise_distance : ndarray (M,)
        Distance from the descriptor to the nearest noise shape.
    nearest_noise : list of str
        The family of that nearest noise shape.
    margin : ndarray (M,)
        ``noise_distance / spread``.
    recommended : str or None
        The first candidate of ``order`` with ``regularity >= min_regularity`` and
        ``margin >= min_margin``; None when none qualifies.
    settings : dict
        Stages, renderings, noise set and thresholds used.
    """

    names: list[str]
    descriptors: np.ndarray
    distances: np.ndarray
    mean: np.ndarray
    variance: np.ndarray
    score: np.ndarray
    order: np.ndarray
    regularity: np.ndarray
    spread: np.ndarray
    noise_distance: np.ndarray
    nearest_noise: list[str]
    margin: np.ndarray
    recommended: str | None
    settings: dict = field(default_factory=dict)
    seconds: float = 0.0

    def qualifies(self) -> np.ndarray:
        """Which candidates meet condition 3 and the confusion-margin minimum, shape (M,) bool."""
        return (self.regularity >= self.settings["min_regularity"]) & (self.margin >= self.settings["min_margin"])

    def rows(self) -> list[dict[str, Any]]:
        """One record per candidate in ranking order."""
        ok = self.qualifies()
        margin_rank = np.empty(len(self.names), int)
        margin_rank[np.argsort(-self.margin, kind="stable")] = np.arange(1, len(self.names) + 1)
        out = []
        for r, i in enumerate(self.order, 1):
            out.append({
                "rank": r, "name": self.names[i], "mean": float(self.mean[i]), "variance": float(self.variance[i]),
                "score": float(self.score[i]), "regularity": float(self.regularity[i]),
                "spread": float(self.spread[i]), "noise_distance": float(self.noise_distance[i]),
                "nearest_noise": self.nearest_noise[i], "margin": float(self.margin[i]),
                "margin_rank": int(margin_rank[i]), "qualifies": bool(ok[i]),
            })
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": "sbplan-symbol-ranking/1",
            "recommended": self.recommended,
            "candidates": self.rows(),
            "names": list(self.names),
            "distances": np.round(self.distances, 6).tolist(),
            "settings": self.settings,
            "seconds": round(self.seconds, 3),
        }

    def table(self) -> str:
        """The ranked table as plain text."""
        head = (f"{'rank':>4}  {'symbol':<18} {'mean d':>7} {'var v':>7} {'v/d':>7} {'regul.':>6} "
                f"{'spread':>7} {'noise d':>7} {'margin':>6}  nearest noise")
        lines = [head, "-" * len(head)]
        for row in self.rows():
            mark = "*" if row["name"] == self.recommended else (" " if row["qualifies"] else "x")
            lines.append(f"{row['rank']:>4}{mark} {row['name']:<18} {row['mean']:7.4f} {row['variance']:7.4f} "
                         f"{row['score']:7.4f} {row['regularity']:6.2f} {row['spread']:7.4f} "
                         f"{row['noise_distance']:7.4f} {row['margin']:6.2f}  {row['nearest_noise']}")
        return "\n".join(lines)


def _check_seq(name: str, values: Sequence[float], *, low: float, low_open: bool = False) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a list of numbers, got {values!r}") from None
    if not vals or not all(math.isfinite(v) and (v > low if low_open else v >= low) for v in vals):
        raise InputError(f"{name}: expected one or more finite numbers {'>' if low_open else '>='} {low}, "
                         f"got {values!r}")
    return vals


def rank_symbols(candidates: Sequence[str] | Mapping[str, Any] | None = None, *,
                 matcher: str | DescriptorMatcher = "fourier", binarizer: str | Binarizer = "otsu",
                 extractor: str | ContourExtractor = "opencv", approximator: str | ContourApproximator = "douglas-peucker",
                 sizes: Sequence[float] = DEFAULT_SIZES, angles: Sequence[float] = DEFAULT_ANGLES,
                 blurs: Sequence[float] = DEFAULT_BLURS, noise_families: str | Sequence[str] | None = None,
                 noise_per_family: int = 12, min_regularity: float = 0.5, min_margin: float = 2.0,
                 seed: int = 0, progress: Callable[[int, int, str], None] | None = None) -> Ranking:
    """Rank candidate symbols by the paper's equations (2)-(4), regularity and confusion margin.

    Parameters
    ----------
    candidates : list of names, or mapping name -> rings, or None
        Registered symbol names (``sbplan.registry.symbol_names()``) or ``{name: [outline, *holes]}``
        polygons in a unit box, y down. None: every registered symbol. At least 2.
    matcher, binarizer, extractor, approximator : str or Stage
        The stages that produce the descriptors.
    sizes, angles, blurs : sequence of float
        The renderings of each candidate (sizes in pixels, angles in degrees, blur sigmas in pixels).
    noise_families : str or sequence of str, optional
        Families of the noise set (:data:`sbplan.symbols.noise.NOISE_FAMILIES`); default all.
    noise_per_family : int
        Noise shapes per family.
    min_regularity : float
        Condition 3: the least share of straight outline a recommended symbol must have.
    min_margin : float
        The least confusion margin a recommended symbol must have.
    seed : int
        Seed of the noise set and of the noise shapes' renderings.
    progress : callable(done, total, name), optional
        Called after each candidate.

    Returns
    -------
    Ranking
    """
    t0 = time.perf_counter()
    if candidates is None:
        candidates = registry.symbol_names()
    if isinstance(candidates, Mapping):
        names = [str(n) for n in candidates]
        rings_of = {n: symbol_rings(candidates[n]) for n in names}
    else:
        if isinstance(candidates, str):
            raise InputError("candidates: expected a list of symbol names, not one string")
        names = [str(n) for n in candidates]
        rings_of = {n: symbol_rings(n) for n in names}
    if len(set(names)) != len(names):
        raise InputError("candidates: names must be unique")
    if len(names) < 2:
        raise InputError(f"candidates: need at least 2 symbols to rank, got {len(names)}")
    sizes = _check_seq("sizes", sizes, low=12)
    angles = _check_seq("angles", angles, low=-3600)
    blurs = _check_seq("blurs", blurs, low=0)
    fams = parse_families(noise_families)
    for key, val in (("min_regularity", min_regularity), ("min_margin", min_margin)):
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val) or val < 0:
            raise InputError(f"{key}: expected a number >= 0, got {val!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed: expected an integer >= 0, got {seed!r}")
    st = _stages(binarizer, extractor, approximator, matcher)
    views = dict(sizes=sizes, angles=angles, blurs=blurs, **st)

    # Shapes shared by every candidate (everything but the candidate's own occluded copies).
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5C0E]))
    shared = [(f, r) for f, r in noise_set(None, families=fams, per_family=noise_per_family, seed=seed)]

    def describe_noise(shapes):
        polys, fams_kept = [], []
        for fam, rings in shapes:
            # each noise shape once, at a random one of the renderings
            p = outline_of(render_view(rings, size=float(rng.choice(sizes)), angle=float(rng.uniform(0, 360)),
                                       blur=float(rng.choice(blurs))),
                           binarizer=st["binarizer"], extractor=st["extractor"], approximator=st["approximator"])
            if p is not None:
                polys.append(p)
                fams_kept.append(fam)
        return st["matcher"].describe_many(polys), fams_kept

    shared_desc, shared_fams = describe_noise(shared)
    total = len(names)
    descriptors, spread, noise_d, nearest, regular = [], [], [], [], []
    for k, name in enumerate(names):
        rings = rings_of[name]
        v = describe_views(rings, **views)
        if len(v) == 0:
            raise InputError(f"symbol {name!r}: no rendering of it yields a contour with these stages")
        desc = np.median(v, axis=0)
        descriptors.append(desc)
        spread.append(float(st["matcher"].distance_matrix(v, desc[None, :])[:, 0].max()))
        own = noise_set(rings, families=[f for f in fams if f == "occluded"] or ["occluded"],
                        per_family=noise_per_family, seed=seed + k) if "occluded" in fams else []
        own_desc, own_fams = describe_noise(own)
        all_desc = np.concatenate([shared_desc, own_desc]) if len(own_desc) else shared_desc
        all_fams = shared_fams + own_fams
        if len(all_desc):
            d = st["matcher"].distance_matrix(all_desc, desc[None, :])[:, 0]
            j = int(np.argmin(d))
            noise_d.append(float(d[j]))
            nearest.append(all_fams[j])
        else:
            noise_d.append(float("inf"))
            nearest.append("-")
        regular.append(regularity(rings))
        if progress is not None:
            progress(k + 1, total, name)
    descriptor_rows = np.stack(descriptors)
    dist = distance_matrix(descriptor_rows, st["matcher"])
    mean, var = distance_statistics(dist)
    score, order = rank_order(dist)
    spread_a, noise_a, regular_a = np.asarray(spread), np.asarray(noise_d), np.asarray(regular)
    margin = noise_a / np.maximum(spread_a, 1e-9)
    ok = (regular_a >= min_regularity) & (margin >= min_margin)
    best = next((names[i] for i in order if ok[i]), None)
    settings = {
        "stages": {k: {"name": s.name, "options": s.config()} for k, s in st.items()},
        "sizes": list(sizes), "angles": list(angles), "blurs": list(blurs),
        "noise_families": list(fams), "noise_per_family": int(noise_per_family),
        "min_regularity": float(min_regularity), "min_margin": float(min_margin), "seed": int(seed),
        "mean_includes_diagonal": True, "variance": "sample variance of row i about its own mean (ddof=1)",
        "spread": "max distance of a rendering from the candidate's median descriptor",
        "regularity": "share of outline length in Douglas-Peucker edges (1.2 px) >= 15% of the size, at 600 px",
    }
    return Ranking(names, descriptor_rows, dist, mean, var, score, order, regular_a, spread_a, noise_a, nearest, margin,
                   best, settings, time.perf_counter() - t0)
