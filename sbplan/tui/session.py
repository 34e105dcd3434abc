"""The operator's session: what the three screens share. Plain Python, no Textual.

Every method here is a thin call into the library (calibration, detection, planning); the screens
run them in worker threads and show the results.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from .. import registry
from ..contracts import StageChoices
from ..detection import Calibration, Detection, Detector
from ..detection.calibration import calibrate, load_calibration, update_calibration
from ..detection.registration import CameraMotion
from ..errors import CalibrationError, InputError, MapFormatError
from ..imageio import load_image
from ..planning import Route, detection_obstacles, plan, replan
from ..workspace import load_workspace

#: Stage kinds the operator can swap on the calibration screen, in pipeline order.
STAGE_KINDS = ("binarizer", "extractor", "approximator", "matcher", "mapper")

#: What the planner avoids of each detected obstacle, with what the operator is told: the obstacle
#: models of :mod:`sbplan.detection.obstacles`, by the names ``sbplan plan --obstacle-model`` takes.
OBSTACLE_MODELS = {
    "mar": "minimum-area rectangles",
    "parts": "rectangles of the parts",
    "outline": "outlines of the occupied cells",
}


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
        ``outline`` (:mod:`sbplan.detection.obstacles`), the names the CLI's ``--obstacle-model`` takes;
        a key of :data:`OBSTACLE_MODELS`.
    route, old_route : Route or None
        The current route and, after a replan, the one it replaced.
    route_invalid : str or None
        Why the current route can no longer be driven (a new obstacle blocks it and replanning
        failed); None while it is valid.
    dynamic : list of ndarray (4, 2)
        Obstacles reported after the detection (placed by the operator or from a newer image).
    robot_fraction : float
        Where the robot is along the route, as a fraction of its length.
    calibration_path : Path or None
        The file the calibration was loaded from or last saved to.
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
    route_invalid: str | None = None
    dynamic: list[np.ndarray] = field(default_factory=list)
    robot_fraction: float = 0.3
    calibration_path: Path | None = None
    _detector: Detector | None = field(default=None, repr=False)

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

    def calibrate(self, stages: StageChoices, progress: Callable[[str, float], None] | None = None) -> Calibration:
        """Calibrate on the loaded reference with the chosen stages (kind -> name);
        ``progress(stage, fraction)`` as for :func:`sbplan.detection.calibration.calibrate`."""
        if self.reference is None:
            raise InputError("reference: open a reference image first")
        cal = calibrate(self.reference, workspace=self.workspace(), progress=progress, **stages)
        self.calibration, self.calibration_path = cal, None
        ws = cal.workspace
        self.start = self.start or ((ws.start_m[0], ws.start_m[1]) if ws.start_m else None)
        self.goal = self.goal or ((ws.goal_m[0], ws.goal_m[1]) if ws.goal_m else None)
        return cal

    def load_calibration(self, path: str | os.PathLike) -> Calibration:
        self.calibration = cal = load_calibration(path)
        self.calibration_path = Path(path)
        return cal

    def save_calibration(self, path: str | os.PathLike) -> Path:
        """Write the calibration to ``path`` (atomically); it becomes the session's calibration file."""
        written = self.require_calibration().save(path)
        self.calibration_path = Path(written)
        return self.calibration_path

    def reanchor(self, frame: np.ndarray | None = None) -> tuple[Calibration, CameraMotion]:
        """The calibration moved to the camera's present pose, measured on ``frame`` (default: the
        current scene): ``(calibration, CameraMotion)``. Nothing changes here; see :meth:`adopt`."""
        cal = self.require_calibration()
        frame = self.scene if frame is None else frame
        if frame is None:
            raise InputError("re-anchor: open a current camera image first (screen 2)")
        return update_calibration(cal, frame)

    def adopt(self, calibration: Calibration) -> None:
        """Use ``calibration`` from now on: what depended on the old one is dropped."""
        self.calibration = calibration
        self.detection = self.route = self.old_route = None
        self.route_invalid = None
        self.dynamic = []

    def load_scene(self, path: str | os.PathLike) -> np.ndarray:
        image = load_image(path)
        self.scene_path, self.scene = Path(path), image
        return image

    def require_calibration(self) -> Calibration:
        if self.calibration is None:
            raise CalibrationError("calibration: calibrate on a reference image first (screen 1)")
        return self.calibration

    def detect(self, image: np.ndarray | None = None) -> Detection:
        """Detect on ``image`` (default: the loaded scene) with the calibrated stages.

        One :class:`~sbplan.detection.Detector` per calibration: it keeps the camera's last pose,
        which starts the next frame's registration."""
        cal = self.require_calibration()
        image = self.scene if image is None else image
        if image is None:
            raise InputError("scene: open a scene image first")
        if self._detector is None or self._detector.calibration is not cal:
            self._detector = Detector(cal)
        return self._detector(image)

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

    def plan(self, start: Any = None) -> Route:
        """Plan from ``start`` (default: the session's start) to the goal around the detected
        obstacles and the dynamic ones."""
        cal = self.require_calibration()
        start = self.start if start is None else start
        if start is None or self.goal is None:
            raise InputError("start/goal: set both (type x, y in metres or move the cursor and press s / g)")
        return plan(self.obstacles_m() + list(self.dynamic), start, self.goal,
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

    def not_yet_dynamic(self, obstacles: list[np.ndarray]) -> list[np.ndarray]:
        """Those of ``obstacles`` that are not already dynamic obstacles (nor repeated among
        themselves): the same obstacle reported twice is one obstacle."""
        kept: list[np.ndarray] = []
        for ob in obstacles:
            ob = np.asarray(ob, float)
            if not any(o.shape == ob.shape and np.allclose(o, ob, atol=1e-9) for o in [*self.dynamic, *kept]):
                kept.append(ob)
        return kept
