"""The workspace: how the grid maps to metres, the robot's size and a default route.

World frame: metres, x to the right along the grid's columns, y up toward row 0 (ROS REP-103 and
nav2 conventions). ``workspace.toml``::

    [grid]
    pitch_m = [0.5, 0.5]   # metres between neighbouring symbol centres along columns (x), rows (y)
    [origin]
    xy_m = [0.25, 0.25]    # world (x, y) of the centre of the bottom-left symbol (row = rows-1, col = 0)
    [robot]
    radius_m = 0.15
    [route]
    start_m = [0.1, 1.4]
    goal_m = [3.9, 1.6]
    [georeference]         # optional: where the floor is on the Earth (GeoJSON in WGS84 lon/lat)
    latitude_deg = 52.5163   # WGS84 latitude and longitude of the world point (0, 0)
    longitude_deg = 13.3777
    heading_deg = 90.0       # compass heading of the floor's x axis: degrees clockwise from true north

Without ``[georeference]`` GeoJSON stays in the local frame (metres); see :class:`Georeference`.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import MapFormatError


#: WGS84: semi-major axis (m) and first eccentricity squared.
_A = 6378137.0
_E2 = 6.69437999014e-3


@dataclass(frozen=True)
class Georeference:
    """Where the world frame lies on the Earth.

    The floor is a plane; its world point (0, 0) is at WGS84 ``latitude_deg``, ``longitude_deg``,
    and its x axis points at the compass heading ``heading_deg`` (degrees clockwise from true
    north: 90 puts x east and y north, ROS's ENU; 0 puts x north and y west). The plane is the
    tangent plane of the WGS84 ellipsoid at that point: a world point is mapped through
    east-north-up to Earth-centred coordinates and from there, exactly, to latitude and longitude.

    Parameters
    ----------
    latitude_deg : float, in (-90, 90)
    longitude_deg : float, in [-180, 180]
    heading_deg : float
    """

    latitude_deg: float
    longitude_deg: float
    heading_deg: float

    def __post_init__(self) -> None:
        for name in ("latitude_deg", "longitude_deg", "heading_deg"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise MapFormatError(f"georeference.{name}: must be a finite number, got {v!r}")
        if not -90.0 < self.latitude_deg < 90.0:
            raise MapFormatError(f"georeference.latitude_deg: must lie in (-90, 90), got {self.latitude_deg}")
        if not -180.0 <= self.longitude_deg <= 180.0:
            raise MapFormatError(f"georeference.longitude_deg: must lie in [-180, 180], got {self.longitude_deg}")

    def _frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The origin in Earth-centred coordinates (3,), and the world x and y axes there (3,) each."""
        lat, lon = math.radians(self.latitude_deg), math.radians(self.longitude_deg)
        sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
        n = _A / math.sqrt(1.0 - _E2 * sl * sl)
        origin = np.array([n * cl * co, n * cl * so, n * (1.0 - _E2) * sl])
        east, north = np.array([-so, co, 0.0]), np.array([-sl * co, -sl * so, cl])
        h = math.radians(self.heading_deg)
        x_axis = math.sin(h) * east + math.cos(h) * north
        y_axis = -math.cos(h) * east + math.sin(h) * north  # x turned 90 degrees counter-clockwise
        return origin, x_axis, y_axis

    def to_lonlat(self, xy: Any) -> np.ndarray:
        """World ``(x, y)`` metres (N, 2) -> WGS84 ``(longitude, latitude)`` degrees (N, 2), GeoJSON's order."""
        pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        origin, ex, ey = self._frame()
        p = origin + pts[:, :1] * ex + pts[:, 1:] * ey
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        lon = np.arctan2(y, x)
        r = np.hypot(x, y)
        lat = np.arctan2(z, r * (1.0 - _E2))
        for _ in range(4):  # converges to far below a millimetre within kilometres of the origin
            s = np.sin(lat)
            n = _A / np.sqrt(1.0 - _E2 * s * s)
            lat = np.arctan2(z + _E2 * n * s, r)
        return np.column_stack([np.degrees(lon), np.degrees(lat)])

    def to_world(self, lonlat: Any) -> np.ndarray:
        """WGS84 ``(longitude, latitude)`` degrees (N, 2), on the ellipsoid -> world ``(x, y)`` metres (N, 2)."""
        ll = np.radians(np.asarray(lonlat, dtype=np.float64).reshape(-1, 2))
        lon, lat = ll[:, 0], ll[:, 1]
        s = np.sin(lat)
        n = _A / np.sqrt(1.0 - _E2 * s * s)
        p = np.column_stack([n * np.cos(lat) * np.cos(lon), n * np.cos(lat) * np.sin(lon), n * (1.0 - _E2) * s])
        origin, ex, ey = self._frame()
        d = p - origin
        return np.column_stack([d @ ex, d @ ey])

    def to_json(self) -> dict:
        return {"latitude_deg": self.latitude_deg, "longitude_deg": self.longitude_deg,
                "heading_deg": self.heading_deg}

    @classmethod
    def from_json(cls, data: Any, *, where: str = "georeference") -> "Georeference":
        if not isinstance(data, dict):
            raise MapFormatError(f"{where}: expected latitude_deg, longitude_deg and heading_deg, got {data!r}")
        missing = [k for k in ("latitude_deg", "longitude_deg", "heading_deg") if k not in data]
        if missing:
            raise MapFormatError(f"{where}: missing {', '.join(missing)}")
        return cls(data["latitude_deg"], data["longitude_deg"], data["heading_deg"])

    @classmethod
    def parse(cls, text: str) -> "Georeference":
        """``"LAT,LON,HEADING"`` (degrees), the command line's form."""
        try:
            lat, lon, heading = (float(v) for v in str(text).split(","))
        except ValueError:
            raise MapFormatError(f"georeference: expected LAT,LON,HEADING in degrees, got {text!r}") from None
        return cls(lat, lon, heading)


#: Largest magnitude (metres) of a pitch, an origin or a route end. A grid of the largest image
#: (thousands of cells a side) then stays far inside planning's 1e12 (a pitch of 1e308 overflowed
#: every world coordinate to infinity, and detection answered with NaN).
MAX_METRES = 1e6


@dataclass(frozen=True)
class Workspace:
    pitch_m: tuple[float, float] = (1.0, 1.0)
    origin_m: tuple[float, float] | None = None  # None: half a pitch, so the grid's corner is (0, 0)
    robot_radius_m: float = 0.0
    start_m: tuple[float, float] | None = None
    goal_m: tuple[float, float] | None = None
    georeference: Georeference | None = None  # None: GeoJSON in the local frame (metres)

    def __post_init__(self) -> None:
        if len(self.pitch_m) != 2 or not np.isfinite(self.pitch_m).all() or min(self.pitch_m) <= 0:
            raise MapFormatError(f"grid.pitch_m: must be two positive numbers, got {self.pitch_m}")
        if not (np.isfinite(self.robot_radius_m) and self.robot_radius_m >= 0):
            raise MapFormatError(f"robot.radius_m: must be a finite number >= 0, got {self.robot_radius_m}")
        for key, v in (("origin.xy_m", self.origin_m), ("route.start_m", self.start_m), ("route.goal_m", self.goal_m)):
            if v is not None and (len(v) != 2 or not np.isfinite(v).all()):
                raise MapFormatError(f"{key}: must be two finite numbers, got {v}")
        bounded: tuple[tuple[str, tuple[float, ...] | None], ...] = (
            ("grid.pitch_m", self.pitch_m), ("robot.radius_m", (self.robot_radius_m,)),
            ("origin.xy_m", self.origin_m), ("route.start_m", self.start_m), ("route.goal_m", self.goal_m))
        for key, values in bounded:
            if values is not None and np.abs(values).max() > MAX_METRES:
                raise MapFormatError(f"{key}: {max(np.abs(values)):g} m is beyond the {MAX_METRES:g} m a floor's "
                                     f"coordinates may reach, got {values}")

    @property
    def origin(self) -> tuple[float, float]:
        if self.origin_m is not None:
            return self.origin_m
        return self.pitch_m[0] / 2, self.pitch_m[1] / 2

    def lattice_to_world(self, col_row: np.ndarray, rows: int) -> np.ndarray:
        """Lattice ``(col, row)`` (N, 2) of a grid with ``rows`` rows -> world ``(x, y)`` metres."""
        cr = np.asarray(col_row, dtype=np.float64).reshape(-1, 2)
        ox, oy = self.origin
        return np.column_stack([ox + cr[:, 0] * self.pitch_m[0], oy + (rows - 1 - cr[:, 1]) * self.pitch_m[1]])

    def world_to_lattice(self, xy: np.ndarray, rows: int) -> np.ndarray:
        """The inverse of :meth:`lattice_to_world`: world ``(x, y)`` metres (N, 2) -> lattice ``(col, row)``."""
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        ox, oy = self.origin
        return np.column_stack([(p[:, 0] - ox) / self.pitch_m[0], rows - 1 - (p[:, 1] - oy) / self.pitch_m[1]])

    def to_json(self) -> dict:
        return {"pitch_m": list(self.pitch_m), "origin_m": list(self.origin), "robot_radius_m": self.robot_radius_m,
                "start_m": list(self.start_m) if self.start_m else None,
                "goal_m": list(self.goal_m) if self.goal_m else None,
                "georeference": self.georeference.to_json() if self.georeference else None}

    @classmethod
    def from_json(cls, data: dict) -> "Workspace":
        def pair(v):
            return None if v is None else (float(v[0]), float(v[1]))
        geo = data.get("georeference")
        return cls(pair(data["pitch_m"]), pair(data.get("origin_m")), float(data.get("robot_radius_m", 0.0)),
                   pair(data.get("start_m")), pair(data.get("goal_m")),
                   None if geo is None else Georeference.from_json(geo, where="workspace.georeference"))


def _pair(table: dict, key: str, where: str, required: bool = False) -> tuple[float, float] | None:
    v = table.get(key)
    if v is None:
        if required:
            raise MapFormatError(f"{where}: missing {key}")
        return None
    if isinstance(v, (int, float)):
        v = [v, v]
    try:
        if isinstance(v, (str, bytes)):
            raise TypeError
        x, y = (float(t) for t in v)
    except (TypeError, ValueError):
        raise MapFormatError(f"{where}: {key} must be a number or two numbers, got {v!r}") from None
    return x, y


def _required_pair(table: dict, key: str, where: str) -> tuple[float, float]:
    pair = _pair(table, key, where, required=True)
    assert pair is not None  # _pair raises when a required key is missing
    return pair


def load_workspace(path: str | os.PathLike) -> Workspace:
    """Read a ``workspace.toml`` (or the one in a map folder)."""
    p = Path(path)
    if p.is_dir():
        p = p / "workspace.toml"
    if not p.exists():
        raise MapFormatError(f"{p}: no such file")
    if not p.is_file():
        raise MapFormatError(f"{p}: is not a regular file (a device, FIFO or socket)")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise MapFormatError(f"{p}: not valid TOML ({exc})") from None
    tables = {}
    for key in ("grid", "origin", "robot", "route"):
        tables[key] = data.get(key, {})
        if not isinstance(tables[key], dict):
            raise MapFormatError(f"{p}: [{key}] must be a table")
    radius = tables["robot"].get("radius_m", 0.0)
    if isinstance(radius, bool) or not isinstance(radius, (int, float)):
        raise MapFormatError(f"{p} [robot]: radius_m must be a number, got {radius!r}")
    pitch = _pair(tables["grid"], "pitch_m", f"{p} [grid]", required=True)
    assert pitch is not None  # required: _pair raised otherwise
    geo = data.get("georeference")
    try:
        return Workspace(
            pitch_m=pitch,
            origin_m=_pair(tables["origin"], "xy_m", f"{p} [origin]"),
            robot_radius_m=float(radius),
            start_m=_pair(tables["route"], "start_m", f"{p} [route]"),
            goal_m=_pair(tables["route"], "goal_m", f"{p} [route]"),
            georeference=None if geo is None else Georeference.from_json(geo, where="[georeference]"),
        )
    except MapFormatError as exc:
        raise MapFormatError(f"{p}: {exc}") from None
