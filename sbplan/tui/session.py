"""The operator's session: what the three screens share. Plain Python, no Textual.

Every method here is a thin call into the library (calibration, detection, planning); the screens
run them in worker threads and show the results.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from .. import registry
from ..contracts import StageChoices
from ..detection import Calibration, Detection, Detector
from ..detection.calibration import calibrate, load_calibration
from ..errors import CalibrationError, InputError, MapFormatError
from ..imageio import load_image
from ..planning import Route, detection_obstacles, plan, replan
from ..workspace import load_workspace

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
    return {kind: getattr(registry, f"{kind}_names")() for kind in STAGE_KINDS}


def square(centre: Sequence[float] | np.ndarray, side: float) -> np.ndarray:
    """A square obstacle (4, 2) ``(x, y)`` metres, axis-aligned, of ``side`` around ``centre``."""
    x, y = (float(v) for v in centre)
    h = side / 2
    return np.array([[x - h, y - h], [x + h, y - h], [x + h, y + h], [x - h, y + h]])


def obstacle_arrays(detection: Detection, model: str | None = None) -> list[np.ndarray]:
    """A detection's obstacles as the planner takes them under the obstacle model ``model``
    (``detection_obstacles``; default ``parts``), in its order, as (M, 2) arrays ``(x, y)`` metres
    (what the map view draws)."""
    return [np.asarray(p.exterior.coords)[:-1] for p in detection_obstacles(detection, use=model).polygons]


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
    obstacle_model : str
        What stands for each detected obstacle when planning: ``mar``, ``parts`` (the default) or
        ``outline`` (:mod:`sbplan.detection.obstacles`), the names the CLI's ``--obstacle-model`` takes.
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
    calibration: Calibration | None = None
    detection: Detection | None = None
    start: tuple[float, float] | None = None
    goal: tuple[float, float] | None = None
    planner: str = "aux-corner"
    obstacle_model: str = "parts"
    route: Route | None = None
    old_route: Route | None = None
    dynamic: list[np.ndarray] = field(default_factory=list)
    robot_fraction: float = 0.3

    @classmethod
    def from_map(cls, map_dir: str | os.PathLike | None) -> "Session":
        """A session on a map folder; the reference and the first scene are picked, not loaded."""
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
        if self.map_dir is not None and (self.map_dir / "workspace.toml").is_file():
            return load_workspace(self.map_dir)
        return None

    # -- the job -------------------------------------------------------------------------------
    def load_reference(self, path: str | os.PathLike) -> np.ndarray:
        """Load the reference image at ``path``, or the reference.png of the map folder ``path``.

        A map folder starts a new session on that map: its workspace, its first scene, and no
        calibration, detection, route or start/goal carried over from the previous map.
        """
        p = Path(path)
        if p.is_dir():
            if not (p / "reference.png").is_file():
                raise MapFormatError(f"{path}: not a map folder (no reference.png)")
            fresh = Session.from_map(p)
            image = load_image(p / "reference.png")  # (fresh.reference_path)
            fresh.planner, fresh.obstacle_model = self.planner, self.obstacle_model
            self.__dict__.update(fresh.__dict__)
            self.reference = image
            return image
        image = load_image(p)
        self.reference_path, self.reference = p, image
        return image

    def calibrate(self, stages: StageChoices) -> Calibration:
        """Calibrate on the loaded reference with the chosen stages (kind -> name)."""
        if self.reference is None:
            raise InputError("reference: open a reference image first")
        cal = calibrate(self.reference, workspace=self.workspace(), **stages)
        self.calibration = cal
        ws = cal.workspace
        self.start = self.start or ((ws.start_m[0], ws.start_m[1]) if ws.start_m else None)
        self.goal = self.goal or ((ws.goal_m[0], ws.goal_m[1]) if ws.goal_m else None)
        return cal

    def load_calibration(self, path: str | os.PathLike) -> Calibration:
        self.calibration = cal = load_calibration(path)
        return cal

    def load_scene(self, path: str | os.PathLike) -> np.ndarray:
        image = load_image(path)
        self.scene_path, self.scene = Path(path), image
        return image

    def require_calibration(self) -> Calibration:
        if self.calibration is None:
            raise CalibrationError("calibration: calibrate on a reference image first (screen 1)")
        return self.calibration

    def detect(self, image: np.ndarray | None = None) -> Detection:
        """Detect on ``image`` (default: the loaded scene) with the calibrated stages."""
        cal = self.require_calibration()
        image = self.scene if image is None else image
        if image is None:
            raise InputError("scene: open a scene image first")
        return Detector(cal)(image)

    def obstacles_m(self) -> list[np.ndarray]:
        """The detection's obstacles in metres under the obstacle model, (M, 2) ``(x, y)`` each (what
        the planner avoids)."""
        return [] if self.detection is None else obstacle_arrays(self.detection, self.obstacle_model)

    def clearance_m(self) -> list[np.ndarray]:
        """The planner's clearance around :meth:`obstacles_m` (enlarged by the robot radius, clipped
        to the floor), as outer rings in metres: what the map draws around the obstacles."""
        from ..detection.exports import planner_view

        if self.detection is None:
            return []
        _, zones = planner_view(self.detection, self.obstacle_model)
        return [np.asarray(z.exterior.coords) for z in zones]

    def plan(self) -> Route:
        """Plan from start to goal around the detected obstacles and the dynamic ones."""
        cal = self.require_calibration()
        if self.start is None or self.goal is None:
            raise InputError("start/goal: set both (type x, y in metres or move the cursor and press s / g)")
        return plan(self.obstacles_m() + list(self.dynamic), self.start, self.goal,
                    robot_radius=cal.workspace.robot_radius_m, planner=self.planner, bounds=cal.world_bounds())

    def robot_position(self) -> np.ndarray | None:
        if self.route is None:
            return None
        return point_along(self.route.waypoints, self.robot_fraction)

    def replan(self, new_obstacles: list[np.ndarray]) -> Route:
        """Replan from the robot's position on the current route around ``new_obstacles``."""
        if self.route is None:
            raise InputError("route: plan a route first (p)")
        return replan(self.route, self.robot_position(), new_obstacles)

    def new_obstacles_in(self, detection: Detection) -> list[np.ndarray]:
        """The polygons (under the obstacle model) of ``detection``'s obstacles that cover a cell the
        current detection left free."""
        known = set(self.detection.occupied_cells) if self.detection is not None else set()
        return [np.asarray(p) for ob in detection.obstacles if set(map(tuple, ob.cells)) - known
                for p in ob.polygons_m(self.obstacle_model)]
