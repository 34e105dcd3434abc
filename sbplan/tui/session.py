"""The operator's session: what the three screens share. Plain Python, no Textual.

Every method here is a thin call into the library (calibration, detection, planning); the screens
run them in worker threads and show the results.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: Stage kinds the operator can swap on the calibration screen, in pipeline order.
STAGE_KINDS = ("binarizer", "extractor", "approximator", "matcher", "mapper")


def display_path(path: str | os.PathLike | None) -> str:
    """A path as the operator typed it, relative to the working folder when it lies inside it."""
    if path is None:
        return ""
    p = Path(path)
    try:
        return str(p.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(p)


def stage_names() -> dict[str, list[str]]:
    """The installed stage names of every selectable kind, from the plugin registry."""
    from .. import registry

    return {kind: getattr(registry, f"{kind}_names")() for kind in STAGE_KINDS}


def square(centre: Any, side: float) -> np.ndarray:
    """A square obstacle (4, 2) ``(x, y)`` metres, axis-aligned, of ``side`` around ``centre``."""
    x, y = (float(v) for v in centre)
    h = side / 2
    return np.array([[x - h, y - h], [x + h, y - h], [x + h, y + h], [x - h, y + h]])


def obstacle_arrays(detection: Any) -> list[np.ndarray]:
    """A detection's obstacles as the planner takes them (``detection_obstacles``), in its order,
    as (M, 2) arrays ``(x, y)`` metres (what the map view draws)."""
    from ..planning import detection_obstacles

    return [np.asarray(p.exterior.coords)[:-1] for p in detection_obstacles(detection).polygons]


def point_along(waypoints: np.ndarray, fraction: float) -> np.ndarray:
    """The point at ``fraction`` (0..1) of a polyline's length; waypoints (K, 2) ``(x, y)``."""
    wp = np.asarray(waypoints, float).reshape(-1, 2)
    if len(wp) == 1:
        return wp[0].copy()
    seg = np.hypot(*np.diff(wp, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = float(np.clip(fraction, 0.0, 1.0)) * cum[-1]
    i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1))
    t = 0.0 if seg[i] == 0 else (s - cum[i]) / seg[i]
    return wp[i] + t * (wp[i + 1] - wp[i])


@dataclass
class Session:
    """State of one operator session.

    Attributes
    ----------
    map_dir : Path or None
        The map folder (reference.png, scene-*.png, workspace.toml) given on the command line.
    reference_path, scene_path : Path or None
    reference, scene : ndarray (H, W) or (H, W, 3) or None
        The images as loaded.
    calibration, detection : Calibration, Detection or None
    start, goal : (x, y) metres or None
    planner : str
    route, old_route : Route or None
        The current route and, after a replan, the one it replaced.
    dynamic : list of ndarray (4, 2)
        Obstacles reported after the detection (placed by the operator or from a newer image).
    robot_fraction : float
        Where the robot is along the route, as a fraction of its length.
    """

    map_dir: Path | None = None
    reference_path: Path | None = None
    scene_path: Path | None = None
    reference: np.ndarray | None = None
    scene: np.ndarray | None = None
    calibration: Any = None
    detection: Any = None
    start: tuple[float, float] | None = None
    goal: tuple[float, float] | None = None
    planner: str = "aux-corner"
    route: Any = None
    old_route: Any = None
    dynamic: list[np.ndarray] = field(default_factory=list)
    robot_fraction: float = 0.3

    @classmethod
    def from_map(cls, map_dir: str | os.PathLike | None) -> "Session":
        """A session on a map folder; the reference and the first scene are picked, not loaded."""
        from ..errors import MapFormatError

        s = cls()
        if map_dir is None:
            return s
        folder = Path(map_dir)
        if not folder.is_dir():
            raise MapFormatError(f"{folder}: no such map folder")
        s.map_dir = folder
        if (folder / "reference.png").is_file():
            s.reference_path = folder / "reference.png"
        scenes = sorted(folder.glob("scene-*.png"))
        if scenes:
            s.scene_path = scenes[0]
        return s

    # -- paths ---------------------------------------------------------------------------------
    @property
    def out_dir(self) -> Path:
        """Default folder for what the operator saves: out/<map name>."""
        return Path("out") / (self.map_dir.name if self.map_dir else "session")

    def workspace(self):
        """The map's workspace.toml, or None when the map has none."""
        from ..workspace import load_workspace

        if self.map_dir is not None and (self.map_dir / "workspace.toml").is_file():
            return load_workspace(self.map_dir)
        return None

    # -- the job -------------------------------------------------------------------------------
    def load_reference(self, path: str | os.PathLike) -> np.ndarray:
        """Load the reference image at ``path``, or the reference.png of the map folder ``path``.

        A map folder starts a new session on that map: its workspace, its first scene, and no
        calibration, detection, route or start/goal carried over from the previous map.
        """
        from ..errors import MapFormatError
        from ..imageio import load_image

        p = Path(path)
        if p.is_dir():
            if not (p / "reference.png").is_file():
                raise MapFormatError(f"{path}: not a map folder (no reference.png)")
            fresh = Session.from_map(p)
            image = load_image(fresh.reference_path)
            fresh.planner = self.planner
            self.__dict__.update(fresh.__dict__)
            self.reference = image
            return image
        image = load_image(p)
        self.reference_path, self.reference = p, image
        return image

    def calibrate(self, stages: dict[str, str]) -> Any:
        """Calibrate on the loaded reference with the chosen stages (kind -> name)."""
        from ..detection.calibration import calibrate
        from ..errors import InputError

        if self.reference is None:
            raise InputError("reference: open a reference image first")
        cal = calibrate(self.reference, workspace=self.workspace(), **stages)
        self.calibration = cal
        ws = cal.workspace
        self.start = self.start or (tuple(ws.start_m) if ws.start_m else None)
        self.goal = self.goal or (tuple(ws.goal_m) if ws.goal_m else None)
        return cal

    def load_calibration(self, path: str | os.PathLike) -> Any:
        from ..detection.calibration import load_calibration

        self.calibration = load_calibration(path)
        return self.calibration

    def load_scene(self, path: str | os.PathLike) -> np.ndarray:
        from ..imageio import load_image

        image = load_image(path)
        self.scene_path, self.scene = Path(path), image
        return image

    def require_calibration(self):
        from ..errors import CalibrationError

        if self.calibration is None:
            raise CalibrationError("calibration: calibrate on a reference image first (screen 1)")
        return self.calibration

    def detect(self, image: np.ndarray | None = None) -> Any:
        """Detect on ``image`` (default: the loaded scene) with the calibrated stages."""
        from ..detection import Detector
        from ..errors import InputError

        cal = self.require_calibration()
        image = self.scene if image is None else image
        if image is None:
            raise InputError("scene: open a scene image first")
        return Detector(cal)(image)

    def obstacles_m(self) -> list[np.ndarray]:
        """The detection's obstacles in metres, (M, 2) ``(x, y)`` each (what the planner avoids)."""
        return [] if self.detection is None else obstacle_arrays(self.detection)

    def plan(self) -> Any:
        """Plan from start to goal around the detected obstacles and the dynamic ones."""
        from ..errors import InputError
        from ..planning import plan

        cal = self.require_calibration()
        if self.start is None or self.goal is None:
            raise InputError("start/goal: set both (type x, y in metres or move the cursor and press s / g)")
        return plan(self.obstacles_m() + list(self.dynamic), self.start, self.goal,
                    robot_radius=cal.workspace.robot_radius_m, planner=self.planner, bounds=cal.world_bounds())

    def robot_position(self) -> np.ndarray | None:
        if self.route is None:
            return None
        return point_along(self.route.waypoints, self.robot_fraction)

    def replan(self, new_obstacles: list[np.ndarray]) -> Any:
        """Replan from the robot's position on the current route around ``new_obstacles``."""
        from ..errors import InputError
        from ..planning import replan

        if self.route is None:
            raise InputError("route: plan a route first (p)")
        return replan(self.route, self.robot_position(), new_obstacles)

    def new_obstacles_in(self, detection: Any) -> list[np.ndarray]:
        """The MARs of ``detection``'s obstacles that cover a cell the current detection left free."""
        known = set(self.detection.occupied_cells) if self.detection is not None else set()
        return [a for ob, a in zip(detection.obstacles, obstacle_arrays(detection)) if set(map(tuple, ob.cells)) - known]
