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
                        help="folder for the calibration, result, pictures and maps (default: out/<map name>)")
    parser.add_argument("--planner", default="aux-corner", help="planner stage (default: %(default)s)")
    from .detect import add_georef_argument

    add_georef_argument(parser)


def run(args: argparse.Namespace) -> int:
    from ..detection import exports
    from ..detection.calibration import calibrate
    from ..detection import Detector
    from ..errors import MapFormatError
    from ..imageio import load_image, write_json
    from ..workspace import load_workspace
    from .detect import summary_lines

    folder = Path(args.map)
    if not (folder / "reference.png").is_file():
        raise MapFormatError(f"{folder}: not a map folder (no reference.png); run from the sbplan checkout "
                             "or name a map folder")
    out = Path(args.output or Path("out") / folder.name)
    workspace = load_workspace(folder) if (folder / "workspace.toml").is_file() else None
    print(f"map {folder}: calibrating on reference.png")
    if args.georef is not None:
        from dataclasses import replace

        from ..workspace import Georeference, Workspace

        workspace = replace(workspace or Workspace(), georeference=Georeference.parse(args.georef))
    cal = calibrate(folder / "reference.png", workspace=workspace)
    cal.save(out / "calibration.json")
    print(f"  grid {cal.grid.cols} x {cal.grid.rows}, threshold {cal.threshold:.4f}, margin {cal.margin:.1f}x")
    image = load_image(folder / args.scene)
    detection = Detector(cal)(image)
    print(f"detecting on {args.scene}")
    for line in summary_lines(detection):
        print("  " + line)
    write_json(out / "result.json", detection.to_json())
    exports.write_overlay(out / "overlay.png", image, detection)
    exports.write_occupancy(out / "occupancy.png", detection)
    exports.write_geojson(out / "obstacles.geojson", detection)
    exports.write_nav2(out / "nav2", detection)
    ws = cal.workspace
    if ws.start_m and ws.goal_m:
        from ..planning import detection_obstacles, plan
        from ..planning.ompl_planners import quiet

        quiet(bool(getattr(args, "verbose", False)))  # OMPL's log only with -v
        obstacles = detection_obstacles(detection)
        route = plan(obstacles.polygons, ws.start_m, ws.goal_m, robot_radius=ws.robot_radius_m,
                     planner=args.planner, bounds=obstacles.bounds)
        pts = " -> ".join(f"({x:.2f}, {y:.2f})" for x, y in route.waypoints)
        print(f"route ({route.planner}, {route.status}): {route.length:.3f} m in {route.time_s * 1e3:.2f} ms")
        print(f"  {pts}")
        write_json(out / "route.json", route.to_dict())
    print(f"wrote {out}/: calibration.json, result.json, overlay.png, occupancy.png, obstacles.geojson, nav2/")
    return 0
