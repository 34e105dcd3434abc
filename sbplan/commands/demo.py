"""``sbplan demo``: the main job on an example floor — calibrate, detect, plan a route."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "calibrate, detect and plan a route on an example map (default maps/paper-8x6)"
DESCRIPTION = (
    "Calibrate, detect and plan on an example map, writing every output into one folder: "
    "calibration.json and result.json (pixels of the calibration image; metres of the floor's local "
    "frame, x along the grid's columns, y up toward row 0), overlay.png and occupancy.png (camera "
    "pixels: pictures, not maps), obstacles.geojson (WGS84 longitude/latitude when the floor is "
    "georeferenced, else local metres), nav2/ (a ROS 2 map in local metres) and route.json (local metres).")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("map", nargs="?", default="maps/paper-8x6",
                        help="map folder with reference.png, scene-01.png and workspace.toml (default: %(default)s)")
    parser.add_argument("--scene", default="scene-01.png", help="scene image in the map folder (default: %(default)s)")
    parser.add_argument("-o", "--output", default=None, metavar="DIR",
                        help="folder for the calibration, result, pictures and maps (default: out/<map name>); "
                             "replaced as a whole, so it must be new or hold only a previous demo's files")
    parser.add_argument("--planner", default="aux-corner", help="planner stage (default: %(default)s)")
    from ._stage_options import add_obstacle_model_argument
    from .detect import add_georef_argument

    add_obstacle_model_argument(parser, what="(planner, overlay, GeoJSON, nav2)")
    add_georef_argument(parser)


#: What the demo's output folder holds (it is replaced as a whole, so it may hold nothing else).
DEMO_FILES = ("calibration.json", "result.json", "overlay.png", "occupancy.png", "obstacles.geojson", "nav2",
              "route.json")


def demo_files(calibration, image, detection, route=None, model: str | None = None) -> dict[str, bytes | str]:
    """The demo's output folder as ``{relative path: content}``: calibration, result, pictures,
    GeoJSON, nav2 map and (when planned) the route, written as one unit by :func:`run`. The
    overlay, the GeoJSON and the nav2 map show the obstacle model ``model`` (default ``parts``)."""
    import json

    from ..detection import exports
    from ..files import json_default
    from ..detection.obstacles import DEFAULT_OBSTACLE_MODEL

    model = model or DEFAULT_OBSTACLE_MODEL

    def as_json(obj) -> str:
        return json.dumps(obj, indent=2, default=json_default) + "\n"

    files: dict[str, bytes | str] = {
        "calibration.json": as_json(calibration.to_json()),
        "result.json": as_json(detection.to_json()),
        # the pictures say in their metadata that they are camera pixels: plan refuses them as maps
        "overlay.png": exports.encode_overlay("overlay.png", image, detection, model),
        "occupancy.png": exports.encode_occupancy("occupancy.png", detection),
        "obstacles.geojson": json.dumps(exports.geojson(detection, model), indent=1) + "\n",
        **{f"nav2/{name}": data for name, data in exports.nav2_files(detection, model=model).items()},
    }
    if route is not None:
        files["route.json"] = as_json(route.to_dict())
    return files


def run(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and the pipeline
    from ..detection.calibration import calibrate
    from ..detection import Detector
    from ..detection.grid import size_text
    from ..errors import MapFormatError
    from ..files import check_set_folder, write_file_set
    from ..imageio import load_image
    from ..workspace import load_workspace
    from .detect import summary_lines

    folder = Path(args.map)
    if not (folder / "reference.png").is_file():
        raise MapFormatError(f"{folder}: not a map folder (no reference.png); run from the sbplan checkout "
                             "or name a map folder")
    out = Path(args.output or Path("out") / folder.name)
    check_set_folder(out, DEMO_FILES, what="-o")  # refused before the work, not after it
    workspace = load_workspace(folder) if (folder / "workspace.toml").is_file() else None
    print(f"map {folder}: calibrating on reference.png")
    if args.georef is not None:
        from dataclasses import replace

        from ..workspace import Georeference, Workspace

        workspace = replace(workspace or Workspace(), georeference=Georeference.parse(args.georef))
    cal = calibrate(folder / "reference.png", workspace=workspace)
    print(f"  grid {size_text(cal.grid.cols, cal.grid.rows)}, threshold {cal.threshold:.4f}, margin {cal.margin:.1f}x")
    image = load_image(folder / args.scene)
    detection = Detector(cal)(image)
    print(f"detecting on {args.scene}")
    for line in summary_lines(detection):
        print("  " + line)
    route = None
    ws = cal.workspace
    if ws.start_m and ws.goal_m:
        from ..planning import detection_obstacles, plan
        from ..planning.ompl_planners import quiet
        from .plan import describe

        quiet(bool(getattr(args, "verbose", False)))  # OMPL's log only with -v
        # the detection's obstacles under the obstacle model, on its floor
        obstacles = detection_obstacles(detection, use=args.obstacle_model)
        route = plan(obstacles.polygons, ws.start_m, ws.goal_m, robot_radius=ws.robot_radius_m,
                     planner=args.planner, bounds=obstacles.bounds)
        pts = " -> ".join(f"({x:.2f}, {y:.2f})" for x, y in route.waypoints)
        print(f"{describe(route)}, obstacles as {args.obstacle_model}: {route.length:.3f} m in "
              f"{route.time_s * 1e3:.2f} ms")
        print(f"  {pts}")
    # every file of the run goes into the folder at once: a reader never sees one run's result
    # beside another run's GeoJSON (sbplan.files.write_file_set)
    write_file_set(out, demo_files(cal, image, detection, route, args.obstacle_model), names=DEMO_FILES)
    print(f"wrote {out}/: calibration.json, result.json, overlay.png, occupancy.png, obstacles.geojson, nav2/")
    return 0
