"""``sbplan plan``: a route around the obstacles of a detection result, GeoJSON or occupancy map."""

from __future__ import annotations

import argparse
import json

HELP = "plan a route around obstacles (detection JSON, GeoJSON, nav2 map.yaml or occupancy image)"
DESCRIPTION = (
    "Plan a collision-free route for a disc robot. World frame: x right, y up, metres (detection "
    "JSON, GeoJSON, nav2 map.yaml) or, for a plain PNG/PGM occupancy image, pixels times "
    "--resolution with the origin at the image's bottom-left corner (nav2's frame); dark pixels "
    "(< 128) are obstacles.")


def comma_pair(label: str):
    """An argparse type: two numbers separated by a comma; ``label`` names them in the error."""
    def parse(text: str) -> tuple[float, float]:
        try:
            a, b = (float(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {label}, got {text!r}") from None
        return a, b
    return parse


_xy = comma_pair("X,Y")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--obstacles", required=True, metavar="FILE",
                        help="result.json (sbplan detect), obstacles.geojson, map.yaml (nav2) or map.png/.pgm")
    parser.add_argument("--start", required=True, type=_xy, metavar="X,Y")
    parser.add_argument("--goal", required=True, type=_xy, metavar="X,Y")
    parser.add_argument("--radius", required=True, type=float, metavar="R", help="robot radius (map units)")
    parser.add_argument("--margin", type=float, default=0.0, metavar="M", help="extra safety margin (default 0)")
    parser.add_argument("--planner", default="aux-corner", help="planner stage (default aux-corner; see sbplan plugins)")
    parser.add_argument("--time-limit", type=float, default=1.0, metavar="S", help="seconds (default 1)")
    parser.add_argument("--resolution", type=float, default=None, metavar="M_PER_PX",
                        help="metres per pixel of a plain occupancy image (default 1: pixel units)")
    from ._stage_options import add_obstacle_model_argument

    add_obstacle_model_argument(parser, what="of a detection JSON (a GeoJSON file says its own)")
    # the option's old name, kept for scripts
    parser.add_argument("--use", choices=("mar", "parts", "outline"), default=None, help=argparse.SUPPRESS)
    parser.add_argument("--nav2-image-anywhere", action="store_true",
                        help="a nav2 map.yaml's image may lie outside the YAML's folder (default: refused)")
    parser.add_argument("--json", action="store_true", help="print the route as JSON")
    parser.add_argument("--plot", metavar="PNG", help="draw obstacles, clearance, start, goal and route into PNG")


def describe(route) -> str:
    """The start of the route's first line: "exact" only from a planner that proves its routes
    shortest, then what the planner guarantees, e.g. ``exact route by aux-corner (proven shortest
    for the robot's radius)`` or ``route by rrt-connect (collision-free, not shortest)``."""
    from .. import registry

    stage = registry.planner(route.planner)
    kind = "approximate route" if route.status == "approximate" else ("exact route" if stage.exact else "route")
    return f"{kind} by {route.planner} ({stage.guarantee})"


def run(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without loading numpy, OpenCV and the pipeline
    from ..files import check_outputs
    from ..imageio import write_image
    from ..planning import PlanningMap, load_obstacles, plan
    from ..planning.ompl_planners import quiet

    check_outputs({"--plot": args.plot}, {"--obstacles": args.obstacles}, images=("--plot",))
    quiet(bool(getattr(args, "verbose", False)))
    from ..detection.obstacles import DEFAULT_OBSTACLE_MODEL

    model = args.use or args.obstacle_model
    # a GeoJSON file says which model it holds, unless the command line names one
    named = args.use is not None or args.obstacle_model != DEFAULT_OBSTACLE_MODEL
    obs = load_obstacles(args.obstacles, resolution=args.resolution,
                         obstacle_model=model if named or not str(args.obstacles).lower().endswith(".geojson") else None,
                         image_anywhere=args.nav2_image_anywhere)
    pm = PlanningMap(obs.polygons, robot_radius=args.radius, margin=args.margin, bounds=obs.bounds,
                     include=(args.start, args.goal))
    route = plan(pm, args.start, args.goal, planner=args.planner, time_limit=args.time_limit)
    if args.plot:
        from ..planning.plot import draw_route

        # a plain occupancy image read without a resolution is in pixels; every other source in metres
        image = args.obstacles.lower().endswith((".png", ".pgm", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"))
        units = "px" if image and args.resolution is None else "m"
        write_image(args.plot, draw_route(pm.obstacles, pm.enlarged, pm.bounds, route=route.waypoints,
                                          start=args.start, goal=args.goal, units=units))
    if args.json:
        from .. import registry

        stage = registry.planner(route.planner)
        print(json.dumps({**route.to_dict(), "exact": bool(stage.exact) and route.status == "exact",
                          "guarantee": stage.guarantee}, indent=2))
    else:
        print(f"{describe(route)}: length {route.length:.6g}, {len(route.waypoints)} waypoints, "
              f"{route.time_s * 1e3:.2f} ms")
        for x, y in route.waypoints:
            print(f"  {x:.6g},{y:.6g}")
    return 0
