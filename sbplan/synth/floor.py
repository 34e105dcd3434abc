"""Floor and scene specifications (validated, frozen, hashable) and the symbol outlines.

Units: pixels of the floor plane, which coincides with the image for an untilted, undistorted camera.
Points are ``(x, y)``, origin top-left, y down.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from shapely.geometry import Polygon
from shapely.validation import explain_validity

from .. import registry
from ..contours import as_points
from ..errors import ContourError, SceneError
from ..polygons import signed_area
from .conditions import CONDITIONS, Effects, condition_effects

#: The default floor symbol: asymmetric (no rotational or mirror symmetry), straight pieces, no holes,
#: thick enough (stroke 0.3 of its size) to survive blur at ~40 px. Like the paper's figure 1.
DEFAULT_SYMBOL = "flag"

#: Obstacle kinds and obstacle textures the renderer knows.
OBSTACLE_KINDS = ("box", "cylinder", "blob")
TEXTURES = ("noise", "stripes", "gradient", "labels")
#: Printed patterns ("layouts") at the grid points: the symbol, or one ArUco marker per cell
#: (:mod:`sbplan.synth.aruco`, for comparing with a marker grid on the same scenes).
LAYOUTS = ("symbols", "aruco")


def symbol_outline(symbol: str | Any) -> list[np.ndarray]:
    """The rings of a symbol: ``[outline, *holes]``, each ``(N, 2)`` float64 ``(x, y)``, y down.

    Parameters
    ----------
    symbol : str or array_like or list of array_like
        A registered candidate symbol's name (see ``sbplan.registry.symbol_names()``), one
        ``(N, 2)`` polygon, or a list of polygons (outline first, holes after).

    Returns
    -------
    list of ndarray
        The outline runs counter-clockwise as displayed (negative shoelace area with y down), holes
        clockwise; not closed (the first vertex is not repeated).

    Raises
    ------
    SceneError
        Unknown name, or a polygon that is degenerate or not a valid simple polygon.
    """
    if isinstance(symbol, str):
        symbols = registry.registry().symbols()
        if symbol not in symbols:
            raise SceneError(f"symbol: unknown symbol {symbol!r}; registered: {', '.join(symbols) or 'none'}")
        rings = symbols[symbol].polygon
    else:
        rings = symbol
    if isinstance(rings, np.ndarray) and rings.ndim == 2:
        rings = [rings]
    if not isinstance(rings, (list, tuple)) or len(rings) == 0:
        raise SceneError("symbol: expected a name, an (N, 2) polygon or a list of polygons")
    if not isinstance(rings[0], (list, tuple, np.ndarray)) or np.ndim(rings[0]) == 1:
        rings = [rings]  # a plain list of (x, y) pairs
    try:
        arrs = [as_points(r, name=f"symbol ring {i}") for i, r in enumerate(rings)]
    except ContourError as exc:
        raise SceneError(str(exc)) from None

    poly = Polygon(arrs[0], arrs[1:])
    if not poly.is_valid or poly.area <= 0:
        raise SceneError(f"symbol: not a valid simple polygon ({explain_validity(poly)})")
    out = []
    for i, a in enumerate(arrs):
        if np.allclose(a[0], a[-1]):
            a = a[:-1]
        want_ccw = i == 0  # the outline counter-clockwise as displayed, holes clockwise
        if (signed_area(a) > 0) != want_ccw:
            a = a[::-1]
        out.append(np.ascontiguousarray(a, dtype=np.float64))
    return out


def rings_centroid(rings: Sequence[np.ndarray]) -> tuple[np.ndarray, float]:
    """Centre of area ``(x, y)`` and area of a polygon with holes (paper eq. 1 = shoelace)."""
    total, cx, cy = 0.0, 0.0, 0.0
    for i, a in enumerate(rings):
        x, y = a[:, 0], a[:, 1]
        xn, yn = np.roll(x, -1), np.roll(y, -1)
        cross = x * yn - xn * y
        sign = 1.0 if i == 0 else -1.0  # holes subtract whatever their orientation
        area = 0.5 * cross.sum()
        s = sign * math.copysign(1.0, area) if area else 0.0
        total += s * area
        cx += s * np.sum((x + xn) * cross) / 6.0
        cy += s * np.sum((y + yn) * cross) / 6.0
    if abs(total) < 1e-12:
        raise SceneError("symbol: zero area")
    return np.array([cx / total, cy / total]), abs(total)


def _tuple_rings(rings: list[np.ndarray]) -> tuple:
    return tuple(tuple(map(tuple, np.round(r, 9).tolist())) for r in rings)


def _num(name: str, value: Any, *, low: float | None = None, high: float | None = None,
         low_open: bool = False, integer: bool = False) -> Any:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SceneError(f"{name}: expected a number, got {value!r}")
    if integer and int(value) != value:
        raise SceneError(f"{name}: expected an integer, got {value!r}")
    if not math.isfinite(value):
        raise SceneError(f"{name}: must be finite, got {value!r}")
    if low is not None and (value <= low if low_open else value < low):
        raise SceneError(f"{name}: must be {'>' if low_open else '>='} {low}, got {value!r}")
    if high is not None and value > high:
        raise SceneError(f"{name}: must be <= {high}, got {value!r}")
    return int(value) if integer else float(value)


def _pair(name: str, value: Any) -> tuple[float, float]:
    if isinstance(value, (int, float)):
        value = (value, value)
    try:
        a, b = value
    except (TypeError, ValueError):
        raise SceneError(f"{name}: expected a number or a pair (x, y), got {value!r}") from None
    return (_num(name, a), _num(name, b))


@dataclass(frozen=True, kw_only=True)
class FloorSpec:
    """The physical floor and the fixed camera looking at it.

    Parameters
    ----------
    width, height : int
        Image size in pixels.
    cols, rows : int
        Symbol grid: columns (along x) and rows (along y).
    pitch : (dx, dy) or number or None
        Distance between neighbouring symbol centres in pixels. None: the grid fills the image
        (``dx = width / cols``), or spans it between the margins when margins are given.
    margin : (mx, my) or number or None
        Distance from the image border to the outermost symbol centres. None: the grid is centred.
    col_x, row_y : sequence of float or None
        Explicit centres of area of the columns and rows (overrides pitch and margin; used to
        rebuild the paper's figure 6 exactly).
    symbol : str or polygon
        A registered symbol's name or a polygon / list of rings in a unit box.
    symbol_size : float or None
        Side of the symbol's unit box in pixels; None: 0.45 * min(dx, dy).
    symbol_angle : float
        Rotation of every symbol in degrees (counter-clockwise as displayed).
    background : float
        Floor grey level (0..255) under base lighting. Symbols are dark ink on a lighter floor.
    contrast : float
        Floor level minus ink level.
    texture : float
        Amplitude (grey levels) of the floor's own texture (concrete-like mottling plus grain).
    layout : str
        The printed pattern at the grid points: ``"symbols"``, or ``"aruco"`` (one ArUco marker of
        side ``symbol_size`` per cell, id ``row * cols + col``; see :mod:`sbplan.synth.aruco`).
    tilt : (about_x, about_y) degrees
        Camera tilt from looking straight down (perspective). Same for reference and scenes.
    distortion : float
        Radial lens distortion k1 (positive = barrel), on coordinates normalized by the half diagonal.
    floor_seed : int
        Seed of the floor's texture (a physical property: identical in reference and scenes).
    """

    width: int = 1280
    height: int = 960
    cols: int = 10
    rows: int = 8
    pitch: Any = None
    margin: Any = None
    col_x: Any = None
    row_y: Any = None
    symbol: Any = DEFAULT_SYMBOL
    symbol_size: Any = None
    symbol_angle: float = 0.0
    background: float = 185.0
    contrast: float = 140.0
    texture: float = 6.0
    layout: str = "symbols"
    tilt: Any = (0.0, 0.0)
    distortion: float = 0.0
    floor_seed: int = 0

    def __post_init__(self) -> None:
        s = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731  (frozen dataclass)
        s("width", _num("width", self.width, low=16, integer=True))
        s("height", _num("height", self.height, low=16, integer=True))
        s("cols", _num("cols", self.cols, low=1, integer=True))
        s("rows", _num("rows", self.rows, low=1, integer=True))
        s("background", _num("background", self.background, low=0, high=255))
        s("contrast", _num("contrast", self.contrast, low=0, high=255, low_open=True))
        if self.contrast > self.background:
            raise SceneError(f"contrast: {self.contrast} exceeds background {self.background} (ink below black)")
        s("texture", _num("texture", self.texture, low=0, high=60))
        s("symbol_angle", _num("symbol_angle", self.symbol_angle))
        s("distortion", _num("distortion", self.distortion, low=-0.3, high=0.3))
        s("floor_seed", _num("floor_seed", self.floor_seed, low=0, integer=True))
        for k in ("pitch", "margin"):
            if getattr(self, k) is not None:
                s(k, _pair(k, getattr(self, k)))
        tilt = _pair("tilt", self.tilt)
        if max(abs(tilt[0]), abs(tilt[1])) > 15:
            raise SceneError(f"tilt: at most 15 degrees about each axis, got {tilt}")
        s("tilt", tilt)
        if self.layout not in LAYOUTS:
            raise SceneError(f"layout: unknown layout {self.layout!r}; known: {', '.join(LAYOUTS)}")
        rings = symbol_outline(self.symbol)
        if not isinstance(self.symbol, str):
            s("symbol", _tuple_rings(rings))
        xs, ys = self._grid_axes()
        s("col_x", tuple(float(v) for v in xs))
        s("row_y", tuple(float(v) for v in ys))
        dx = float(np.min(np.diff(xs))) if len(xs) > 1 else float(self.width)
        dy = float(np.min(np.diff(ys))) if len(ys) > 1 else float(self.height)
        if dx <= 0 or dy <= 0:
            raise SceneError("col_x/row_y: centres must increase strictly")
        if self.symbol_size is None and 0.45 * min(dx, dy) < 6:
            raise SceneError(f"cols/rows: a grid of {self.cols} columns × {self.rows} rows does not fit a {self.width} x "
                             f"{self.height} image (pitch {dx:.3g} x {dy:.3g} px leaves symbols under 6 px)")
        size = 0.45 * min(dx, dy) if self.symbol_size is None else self.symbol_size
        s("symbol_size", _num("symbol_size", size, low=0, low_open=True))
        if self.symbol_size < 6:
            raise SceneError(f"symbol_size: {self.symbol_size:.3g} px is too small to render a shape (>= 6)")
        # Rotated symbol's extent from its centre of area, to check it fits its cell and the image.
        ext = self.symbol_extent()
        if 2 * ext[0] >= dx or 2 * ext[1] >= dy:
            raise SceneError(f"symbol_size: {self.symbol_size:.3g} px symbols overlap their neighbours "
                             f"at pitch ({dx:.3g}, {dy:.3g}) px")
        if xs[0] - ext[0] < 0 or xs[-1] + ext[0] > self.width or ys[0] - ext[1] < 0 or ys[-1] + ext[1] > self.height:
            raise SceneError(f"pitch/margin: a grid of {self.cols} columns × {self.rows} rows does not fit a "
                             f"{self.width} x {self.height} image")

    def _grid_axes(self) -> tuple[np.ndarray, np.ndarray]:
        out = []
        for axis, (n, size, given) in enumerate(((self.cols, self.width, self.col_x), (self.rows, self.height, self.row_y))):
            label = "col_x" if axis == 0 else "row_y"
            if given is not None:
                vals = np.asarray(given, dtype=float)
                if vals.shape != (n,) or not np.isfinite(vals).all():
                    raise SceneError(f"{label}: expected {n} finite centres, got {given!r}")
                out.append(vals)
                continue
            pitch = None if self.pitch is None else _pair("pitch", self.pitch)[axis]
            margin = None if self.margin is None else _pair("margin", self.margin)[axis]
            if pitch is not None and pitch <= 0:
                raise SceneError(f"pitch: must be > 0, got {self.pitch!r}")
            if margin is not None and margin < 0:
                raise SceneError(f"margin: must be >= 0, got {self.margin!r}")
            if pitch is None:
                if margin is None:
                    pitch = size / n
                    margin = pitch / 2
                else:
                    pitch = (size - 2 * margin) / (n - 1) if n > 1 else 0.0
                    if n > 1 and pitch <= 0:
                        raise SceneError(f"margin: {self.margin!r} leaves no room for the grid")
            elif margin is None:
                margin = (size - (n - 1) * pitch) / 2
            out.append(margin + pitch * np.arange(n))
        return out[0], out[1]

    # -- derived geometry -------------------------------------------------------------------
    @property
    def pitch_px(self) -> tuple[float, float]:
        """Mean centre-to-centre distance ``(dx, dy)`` in floor pixels."""
        dx = (self.col_x[-1] - self.col_x[0]) / (self.cols - 1) if self.cols > 1 else float(self.width)
        dy = (self.row_y[-1] - self.row_y[0]) / (self.rows - 1) if self.rows > 1 else float(self.height)
        return float(dx), float(dy)

    def rings(self) -> list[np.ndarray]:
        """The symbol's rings in the unit box (see :func:`symbol_outline`)."""
        return symbol_outline(self.symbol if isinstance(self.symbol, str) else [np.array(r) for r in self.symbol])

    def symbol_rings_px(self) -> list[np.ndarray]:
        """The symbol's rings in pixels, rotated, with its centre of area at the origin."""
        rings = [r * self.symbol_size for r in self.rings()]
        c, _ = rings_centroid(rings)
        a = math.radians(self.symbol_angle)
        # counter-clockwise as displayed means the rotation runs the other way in y-down maths
        rot = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
        return [(r - c) @ rot.T for r in rings]

    def symbol_extent(self) -> tuple[float, float]:
        pts = np.vstack(self.symbol_rings_px())
        return float(np.abs(pts[:, 0]).max()), float(np.abs(pts[:, 1]).max())

    def centres(self) -> np.ndarray:
        """Symbol centres of area in the floor plane, shape (rows, cols, 2) ``(x, y)``."""
        gx, gy = np.meshgrid(self.col_x, self.row_y)
        return np.stack([gx, gy], axis=-1)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["symbol"] = self.symbol if isinstance(self.symbol, str) else [list(map(list, r)) for r in self.symbol]
        d["col_x"], d["row_y"] = list(self.col_x), list(self.row_y)
        d["tilt"] = list(self.tilt)
        for k in ("pitch", "margin"):
            if isinstance(d[k], tuple):
                d[k] = list(d[k])
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "FloorSpec":
        d = dict(d)
        for k in ("pitch", "margin", "tilt"):
            if isinstance(d.get(k), list):
                d[k] = tuple(d[k])
        if not isinstance(d.get("symbol"), str):
            d["symbol"] = [np.asarray(r, float) for r in d["symbol"]]
        return cls(**d)


@dataclass(frozen=True, kw_only=True)
class SceneSpec:
    """What stands on the floor and the conditions it is seen under.

    Parameters
    ----------
    n_obstacles : int
        Number of random obstacles (ignored when ``obstacles`` is given).
    kinds : tuple of str
        Obstacle kinds to draw from: ``box``, ``cylinder`` (seen from above), ``blob`` (irregular).
    size : (min, max)
        Obstacle size range in units of the mean grid pitch (a box's longer side, a cylinder's
        diameter, a blob's mean diameter).
    textures : tuple of str
        Obstacle surface textures to draw from: ``noise``, ``stripes``, ``gradient``, ``labels``.
    obstacles : sequence of (K, 2) polygons or None
        Explicit obstacle outlines in floor pixels ``(x, y)`` (maps use these); kinds become
        ``polygon``, textures are still drawn at random.
    condition : str
        A name of :data:`sbplan.synth.CONDITIONS`.
    effects : dict
        Overrides of the condition's :class:`sbplan.synth.conditions.Effects` fields.
    occupied_fraction : float
        A cell is occupied when more than this fraction of its symbol's area is covered.
    near_px : float
        A symbol with no overlap but within this distance of an obstacle is ambiguous (its
        antialiased edge pixels are shared with the obstacle's). The default 1.5 exceeds a pixel's
        diagonal, so a free symbol never shares a pixel with an obstacle.
    min_gap : float
        Minimum gap between random obstacles in pixels (best effort).
    """

    n_obstacles: int = 3
    kinds: tuple = OBSTACLE_KINDS
    size: Any = (0.8, 2.2)
    textures: tuple = TEXTURES
    obstacles: Any = None
    condition: str = "clean"
    effects: Any = field(default_factory=dict)
    occupied_fraction: float = 0.02
    near_px: float = 1.5
    min_gap: float = 10.0

    def __post_init__(self) -> None:
        s = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        s("n_obstacles", _num("n_obstacles", self.n_obstacles, low=0, high=500, integer=True))
        kinds = (self.kinds,) if isinstance(self.kinds, str) else tuple(self.kinds)
        bad = [k for k in kinds if k not in OBSTACLE_KINDS]
        if bad or not kinds:
            raise SceneError(f"kinds: unknown obstacle kinds {bad or '(none given)'}; known: {', '.join(OBSTACLE_KINDS)}")
        s("kinds", kinds)
        tex = (self.textures,) if isinstance(self.textures, str) else tuple(self.textures)
        bad = [t for t in tex if t not in TEXTURES]
        if bad or not tex:
            raise SceneError(f"textures: unknown textures {bad or '(none given)'}; known: {', '.join(TEXTURES)}")
        s("textures", tex)
        lo, hi = _pair("size", self.size)
        if lo <= 0 or hi < lo:
            raise SceneError(f"size: expected 0 < min <= max (in grid pitches), got {self.size!r}")
        s("size", (lo, hi))
        if self.obstacles is not None:
            try:
                obs = tuple(tuple(map(tuple, as_points(o, name=f"obstacles[{i}]").tolist()))
                            for i, o in enumerate(self.obstacles))
            except ContourError as exc:
                raise SceneError(str(exc)) from None
            s("obstacles", obs)
        if self.condition not in CONDITIONS:
            raise SceneError(f"condition: unknown condition {self.condition!r}; known: {', '.join(CONDITIONS)}")
        effects = dict(self.effects or {})
        known = {f.name for f in dataclasses.fields(Effects)}
        bad = sorted(set(effects) - known)
        if bad:
            raise SceneError(f"effects: unknown effects {bad}; known: {', '.join(sorted(known))}")
        s("effects", tuple(sorted(effects.items())))
        self.resolved_effects()  # validates the values
        s("occupied_fraction", _num("occupied_fraction", self.occupied_fraction, low=0, high=1, low_open=True))
        s("near_px", _num("near_px", self.near_px, low=0))
        s("min_gap", _num("min_gap", self.min_gap, low=0))

    def resolved_effects(self):
        """The condition's :class:`Effects` with this scene's overrides applied."""
        return dataclasses.replace(condition_effects(self.condition), **dict(self.effects))

    def to_dict(self) -> dict[str, Any]:
        return {
            "n_obstacles": self.n_obstacles, "kinds": list(self.kinds), "size": list(self.size),
            "textures": list(self.textures),
            "obstacles": None if self.obstacles is None else [list(map(list, o)) for o in self.obstacles],
            "condition": self.condition, "effects": dict(self.effects),
            "occupied_fraction": self.occupied_fraction, "near_px": self.near_px, "min_gap": self.min_gap,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "SceneSpec":
        d = dict(d)
        for k in ("kinds", "textures", "size"):
            if isinstance(d.get(k), list):
                d[k] = tuple(d[k])
        for k, v in list(d.get("effects", {}).items()):
            if isinstance(v, list):
                d["effects"][k] = tuple(v)
        return cls(**d)
