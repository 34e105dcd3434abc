"""``sbplan watch``: watch a camera stream; obstacles, camera movement and routes as JSON lines."""

from __future__ import annotations

import argparse
import json
import signal
import sys
from types import FrameType
from typing import TYPE_CHECKING, Any, Callable, TextIO

from ._stage_options import add_stage_arguments, stage_choices
from .plan import _xy, comma_pair

if TYPE_CHECKING:
    from ..live.watcher import Event

#: A signal's disposition as ``signal.signal`` gives and takes it (a function, SIG_DFL/SIG_IGN, or
#: None for a handler not installed from Python).
SignalHandler = Callable[[int, FrameType | None], Any] | int | None

HELP = "watch a video, image folder, camera or stream URL; print events as JSON lines"
DESCRIPTION = (
    "Run detection on every frame of SOURCE (a video file, a folder of images sorted by name, a camera "
    "index or an RTSP/HTTP URL, read through OpenCV), keep a stable state (a cell changes only after "
    "--hysteresis frames or seconds) and print one JSON line per event: obstacle appeared / moved / left "
    "(with ids that last), camera moved, stalled, reconnected, route, ended. "
    "Exit codes: 0 the source ended (or --max-frames), 1 an error (frames that do not fit the calibration), "
    "2 bad options or a missing file, 3 the source was lost (--max-reopen failed opens in a row), "
    "130 Ctrl-C, 143 SIGTERM. Events: docs/live.md.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", help="video file, folder of images, camera index (0) or rtsp:// / http:// URL")
    parser.add_argument("-c", "--calibration", required=True, help="calibration file from 'sbplan calibrate'")
    parser.add_argument("--events", metavar="FILE", help="append the events to FILE instead of printing them")
    parser.add_argument("--hysteresis", default="3", metavar="N|Ss",
                        help="frames (3) or seconds (0.3s) a cell must be seen changed, or both (3,0.3s) (default 3)")
    parser.add_argument("--stall-timeout", type=float, default=5.0, metavar="S",
                        help="seconds without a frame before 'stalled' and reopening (default 5)")
    parser.add_argument("--backoff", type=comma_pair("FIRST,LARGEST seconds"), default=(0.5, 8.0), metavar="FIRST,MAX",
                        help="seconds between attempts to reopen a failed source, doubling (default 0.5,8)")
    parser.add_argument("--max-reopen", type=int, default=None, metavar="N",
                        help="give up (exit 3) after N failed opens in a row (default: never)")
    parser.add_argument("--realtime", nargs="?", type=float, const=1.0, default=None, metavar="SPEED",
                        help="replay a file or folder at its frame rate (times SPEED) as a camera would deliver it: "
                             "the latest frame only, dropping what the pipeline cannot keep up with")
    parser.add_argument("--fps", type=float, default=None, metavar="F", help="frame rate of an image folder (default 10)")
    parser.add_argument("--start", type=_xy, metavar="X,Y", help="keep a route from here (metres) ...")
    parser.add_argument("--goal", type=_xy, metavar="X,Y", help="... to here, replanned when the obstacles change")
    parser.add_argument("--robot-radius", type=float, metavar="R", help="metres (default: the calibration's workspace's)")
    parser.add_argument("--max-frames", type=int, metavar="N", help="stop after N frames")
    parser.add_argument("--stats", type=float, metavar="S", help="a 'stats' event every S seconds")
    parser.add_argument("--every-frame", action="store_true",
                        help="detect every frame, even one that did not change since the last (slower)")
    parser.add_argument("--whole-frames", action="store_true",
                        help="detect a frame that changed in part whole (default: only the cells near the change, "
                             "keeping the others and the camera's pose)")
    parser.add_argument("--change-threshold", type=float, default=10.0, metavar="LEVELS",
                        help="grey levels some part of the frame (a 2x2 mean every 4 px) must change by for the frame "
                             "to be detected again (default 10)")
    parser.add_argument("--camera-tolerance", type=float, default=1.0, metavar="PX",
                        help="report a camera movement beyond this many pixels (default 1)")
    from ._stage_options import add_obstacle_model_argument

    add_obstacle_model_argument(parser, what="for the route")
    add_stage_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from ..errors import InputError
    from ..live import Watcher, open_source, paced

    source = open_source(args.source, fps=args.fps, timeout=args.stall_timeout)
    if args.realtime is not None:
        if source.live:
            raise InputError("--realtime: only for a file or a folder (a camera or URL is live already)")
        source = paced(source, speed=args.realtime)
    watcher = Watcher(source, args.calibration, hysteresis=args.hysteresis, stall_timeout=args.stall_timeout,
                      backoff=args.backoff, max_reopen=args.max_reopen, start=args.start, goal=args.goal,
                      robot_radius=args.robot_radius, skip_unchanged=not args.every_frame,
                      local=not args.whole_frames,
                      change_threshold=args.change_threshold, camera_tolerance_px=args.camera_tolerance,
                      max_frames=args.max_frames, stats_interval=args.stats, obstacle_model=args.obstacle_model,
                      **stage_choices(args))
    out: TextIO = open(args.events, "a", encoding="utf-8") if args.events else sys.stdout
    previous: dict[int, SignalHandler] = {}

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        watcher.stop("interrupted" if signum == signal.SIGINT else "terminated")
        # a second Ctrl-C stops at once
        signal.signal(signum, previous[signum])

    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            previous[sig] = signal.signal(sig, on_signal)
        except ValueError:  # not the main thread: Ctrl-C stays KeyboardInterrupt, handled by the watcher
            pass
    last: Event | None = None
    try:
        for event in watcher.events():
            out.write(json.dumps(event) + "\n")
            out.flush()
            last = event
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if out is not sys.stdout:
            out.close()
    if last is not None and last["type"] == "ended":
        s = last["stats"]
        print(f"sbplan watch: {last['reason']}: {s['frames_processed']} frames processed, {s['frames_dropped']} dropped, "
              f"{s['frames_corrupt']} corrupt, {s['frames_missing']} missing, {s['reconnects']} reconnects"
              + (f"; {last['error']}" if last["error"] else ""), file=sys.stderr)
    return watcher.exit_code
