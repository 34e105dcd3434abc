"""``sbplan detect``: occupied cells and obstacles of a scene."""

from __future__ import annotations

import argparse
import json

from ._stage_options import add_obstacle_model_argument, add_stage_arguments, stage_choices

HELP = "detect occupied cells and obstacles in a scene image"
DESCRIPTION = (
    "Detect the occupied cells and the obstacles of a scene. Outputs: the JSON result (pixels of the "
    "calibration image, x right, y down; metres of the floor's local frame, x along the grid's columns, "
    "y up toward row 0), the overlay and occupancy pictures (camera pixels: not maps), GeoJSON (WGS84 "
    "longitude/latitude when georeferenced, else local metres) and a nav2 map (local metres).")


def add_georef_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--georef", metavar="LAT,LON,HEADING", default=None,
                        help="where the floor is on the Earth, for GeoJSON: WGS84 latitude and longitude (degrees) "
                             "of the world point (0, 0) and the compass heading of the floor's x axis (degrees "
                             "clockwise from north); overrides workspace.toml's [georeference]")


def with_georeference(calibration, text: str | None):
    """The calibration with the floor georeferenced by ``--georef`` (unchanged without it)."""
    if text is None:
        return calibration
    from dataclasses import replace

    from ..workspace import Georeference

    geo = Georeference.parse(text)
    return replace(calibration, workspace=replace(calibration.workspace, georeference=geo))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", help="current image from the calibrated camera")
    parser.add_argument("-c", "--calibration", required=True, help="calibration file from 'sbplan calibrate'")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    parser.add_argument("-o", "--output", metavar="JSON", help="write the JSON result to this file")
    parser.add_argument("--overlay", metavar="PNG",
                        help="write the scene with cells, footprints, what the planner avoids and numbered obstacles")
    parser.add_argument("--occupancy", metavar="PNG", help="write the occupancy image (paper figure 14)")
    parser.add_argument("--geojson", metavar="FILE",
                        help="write the obstacles as GeoJSON: RFC 7946 WGS84 longitude/latitude when the floor is "
                             "georeferenced (--georef, or [georeference] in the calibration's workspace.toml), "
                             "else the floor's local frame in metres (x along the columns, y up toward row 0)")
    add_georef_argument(parser)
    parser.add_argument("--nav2", metavar="DIR",
                        help="write a ROS 2 nav2 map (map.yaml + map.pgm) into DIR: the floor's local frame, "
                             "metres, origin = the map's bottom-left corner")
    parser.add_argument("--nav2-resolution", type=float, metavar="M", help="nav2 map metres per pixel")
    add_obstacle_model_argument(parser, what="in the overlay, GeoJSON and nav2 map")
    add_stage_arguments(parser)


def summary_lines(detection) -> list[str]:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and the pipeline
    from ..detection.obstacles import axis_angle

    lines = [
        f"symbols: {detection.symbols_expected} expected, {detection.symbols_found} found"
        + (f", {detection.symbols_rescued} more whole in the grey image" if detection.symbols_rescued else ""),
        f"occupied cells: {len(detection.occupied_cells)}  (row, col): "
        + " ".join(f"({r},{c})" for r, c in detection.occupied_cells),
        f"obstacles: {len(detection.obstacles)}",
    ]
    if detection.camera.model != "none":
        lines.insert(0, detection.camera.summary())
    for ob in detection.obstacles:
        j = ob.to_json()
        parts = f", {len(ob.parts_m)} parts" if ob.parts_m is not None and len(ob.parts_m) > 1 else ""
        lines.append(f"  #{ob.id}: {len(ob.cells)} cells, MAR {j['size_m'][0]:.2f} x {j['size_m'][1]:.2f} m "
                     f"at ({j['centre_m'][0]:.2f}, {j['centre_m'][1]:.2f}) m, angle {axis_angle(j['angle_m_deg'], 1):.1f} deg"
                     f"{parts}")
    stages = ", ".join(f"{k}={v}" for k, v in detection.stages.items())
    lines.append(f"stages: {stages}; {detection.timings_ms['total']:.1f} ms")
    return lines


def run(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and the pipeline
    from ..detection import exports
    from ..detection import Detector
    from ..detection.calibration import load_calibration
    from ..files import check_outputs
    from ..imageio import load_image, write_json

    # refused before any work: outputs that are devices, links, folders, inputs or named twice
    check_outputs({"-o": args.output, "--overlay": args.overlay, "--occupancy": args.occupancy,
                   "--geojson": args.geojson, "--nav2": args.nav2},
                  {"scene": args.scene, "-c": args.calibration},
                  folders={"--nav2": exports.NAV2_FILES}, images=("--overlay", "--occupancy"))
    if args.nav2_resolution is not None:
        exports.nav2_resolution(args.nav2_resolution, (1.0, 1.0))
    cal = with_georeference(load_calibration(args.calibration), args.georef)
    image = load_image(args.scene)
    detection = Detector(cal, **stage_choices(args))(image)
    result = detection.to_json()
    if args.output:
        write_json(args.output, result)
    model = args.obstacle_model
    if args.overlay:
        exports.write_overlay(args.overlay, image, detection, model)
    if args.occupancy:
        exports.write_occupancy(args.occupancy, detection)
    if args.geojson:
        exports.write_geojson(args.geojson, detection, model)
    if args.nav2:
        exports.write_nav2(args.nav2, detection, resolution=args.nav2_resolution, model=model)
    if args.json:
        print(json.dumps(result))
    else:
        print("\n".join(summary_lines(detection)))
    return 0
