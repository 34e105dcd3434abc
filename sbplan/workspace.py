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
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import MapFormatError


@dataclass(frozen=True)
class Workspace:
    pitch_m: tuple[float, float] = (1.0, 1.0)
    origin_m: tuple[float, float] | None = None  # None: half a pitch, so the grid's corner is (0, 0)
    robot_radius_m: float = 0.0
    start_m: tuple[float, float] | None = None
    goal_m: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if len(self.pitch_m) != 2 or not np.isfinite(self.pitch_m).all() or min(self.pitch_m) <= 0:
            raise MapFormatError(f"grid.pitch_m: must be two positive numbers, got {self.pitch_m}")
        if not (np.isfinite(self.robot_radius_m) and self.robot_radius_m >= 0):
            raise MapFormatError(f"robot.radius_m: must be a finite number >= 0, got {self.robot_radius_m}")
        for key, v in (("origin.xy_m", self.origin_m), ("route.start_m", self.start_m), ("route.goal_m", self.goal_m)):
            if v is not None and (len(v) != 2 or not np.isfinite(v).all()):
                raise MapFormatError(f"{key}: must be two finite numbers, got {v}")

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
                "goal_m": list(self.goal_m) if self.goal_m else None}

    @classmethod
    def from_json(cls, data: dict) -> "Workspace":
        def pair(v):
            return None if v is None else (float(v[0]), float(v[1]))
        return cls(pair(data["pitch_m"]), pair(data.get("origin_m")), float(data.get("robot_radius_m", 0.0)),
                   pair(data.get("start_m")), pair(data.get("goal_m")))


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
    try:
        return Workspace(
            pitch_m=pitch,
            origin_m=_pair(tables["origin"], "xy_m", f"{p} [origin]"),
            robot_radius_m=float(radius),
            start_m=_pair(tables["route"], "start_m", f"{p} [route]"),
            goal_m=_pair(tables["route"], "goal_m", f"{p} [route]"),
        )
    except MapFormatError as exc:
        raise MapFormatError(f"{p}: {exc}") from None
