"""``sbplan serve``: the planner service on the network (HTTP + WebSocket), see docs/robots.md."""

from __future__ import annotations

import argparse
import os

from ..errors import InputError, PluginError

HELP = "serve one workspace over HTTP and WebSocket: obstacles, nav2 map, routes pushed to robots"
DESCRIPTION = (
    "Serve a calibration's floor: POST frames (or --source DIR) to detect obstacles, plan routes, get "
    "them replanned and pushed over WS /events when a new obstacle blocks them. Listens on 127.0.0.1 "
    "unless --host says otherwise; then a bearer token (--token or SBPLAN_TOKEN) is required for "
    "everything but /health. OpenAPI at /docs. Needs the serve extra: pip install 'sbplan[serve]'. "
    "GET /obstacles.geojson is WGS84 longitude/latitude when the floor is georeferenced (--georef, or "
    "[georeference] in the calibration's workspace.toml), else the floor's local metres; routes and "
    "the nav2 map are in local metres.")

#: Environment variable holding the bearer token (safer than --token, which `ps` shows).
TOKEN_ENV = "SBPLAN_TOKEN"
MIN_TOKEN = 16


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-c", "--calibration", required=True, metavar="CALIBRATION.json")
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to listen on (default 127.0.0.1: this machine only; 0.0.0.0: every interface, needs a token)")
    parser.add_argument("--port", type=int, default=8765, help="TCP port (default 8765; 0: any free port)")
    parser.add_argument("--source", metavar="DIR",
                        help="live source: a folder of PNG/JPEG frames, read in name order (default: frames are posted)")
    parser.add_argument("--interval", type=float, default=0.0, metavar="S",
                        help="seconds between two frames of --source (default 0: as fast as detection)")
    parser.add_argument("--token", help=f"bearer token clients must send (default: ${TOKEN_ENV}); required with a non-loopback --host")
    from ._stage_options import add_obstacle_model_argument

    add_obstacle_model_argument(parser, what="(routes, GeoJSON, nav2)")
    # the option's old name, kept for scripts
    parser.add_argument("--use", choices=("mar", "parts", "outline"), default=None, help=argparse.SUPPRESS)
    parser.add_argument("--planner", default="aux-corner", help="planner stage for routes (default aux-corner)")
    parser.add_argument("--time-limit", type=float, default=1.0, metavar="S", help="seconds per planning query (default 1)")
    parser.add_argument("--max-routes", type=int, default=256, metavar="N",
                        help="routes kept; the least recently changed is dropped beyond (default 256)")
    parser.add_argument("--planner-processes", type=int, default=None, metavar="N",
                        help="processes planning route requests (default: one per core but one, at least one; 0: on the service's "
                             "state thread)")
    parser.add_argument("--max-body-mb", type=float, default=32.0, metavar="MB", help="largest frame upload (default 32)")
    parser.add_argument("--max-pixels", type=int, default=40_000_000, metavar="N",
                        help="largest image, width x height, read from its header before decoding (default 40e6)")
    parser.add_argument("--access-log", action="store_true", help="log every request")
    from .detect import add_georef_argument

    add_georef_argument(parser)


def run(args: argparse.Namespace) -> int:
    # imported when the command runs: the CLI starts without numpy, OpenCV or the service, and the
    # service's libraries come with the serve extra
    try:
        import fastapi  # noqa: F401
        import uvicorn  # noqa: F401
    except ImportError as exc:
        raise PluginError(f"sbplan serve needs the serve extra: pip install 'sbplan[serve]' (missing: {exc.name})") from None
    from ..detection import load_calibration
    from ..service import Limits, Service
    from ..service.app import create_app
    from ..service.server import address, bind, freeze_startup_objects, is_loopback, make_server
    from ..service.sources import open_source
    from ..service.workers import default_processes

    token = args.token or os.environ.get(TOKEN_ENV) or None
    if token is None and not is_loopback(args.host):
        raise InputError(f"--host {args.host} opens the service to the network: give a bearer token with --token "
                         f"or ${TOKEN_ENV}")
    if token is not None and len(token) < MIN_TOKEN:
        raise InputError(f"token: use at least {MIN_TOKEN} characters, e.g. "
                         "python3 -c 'import secrets; print(secrets.token_urlsafe())'")
    if args.max_body_mb <= 0 or args.max_pixels <= 0:
        raise InputError("--max-body-mb and --max-pixels must be > 0")
    processes = default_processes() if args.planner_processes is None else args.planner_processes
    if processes < 0:
        raise InputError(f"--planner-processes: must be >= 0, got {processes}")
    from .detect import with_georeference

    calibration = with_georeference(load_calibration(args.calibration), args.georef)
    source = open_source(args.source, interval=args.interval) if args.source else None
    service = Service(calibration, use=args.use or args.obstacle_model, planner=args.planner, time_limit=args.time_limit,
                      max_routes=args.max_routes, planner_processes=processes,
                      limits=Limits(max_body=int(args.max_body_mb * 2**20), max_pixels=args.max_pixels))
    try:
        sock = bind(args.host, args.port)
        host, port = address(sock)
        shown = f"[{host}]" if ":" in host else host
        print(f"sbplan serve: http://{shown}:{port} (API: /docs, events: ws://{shown}:{port}/events"
              f"{', bearer token required' if token else ''})", flush=True)
        server = make_server(create_app(service, token=token, source=source), access_log=args.access_log)
        server.config.load()  # uvicorn's protocol modules imported now, before the freeze
        freeze_startup_objects()
        server.run(sockets=[sock])
    finally:
        service.close()
    return 0
