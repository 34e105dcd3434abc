"""``sbplan bench serve``: route requests per second and their latency through the real service.

The floor: a rendered 20 x 15 grid (1280 x 960 px, pitch 0.5 m: 10 m x 7.5 m) with 50 box
obstacles, each over one cell and at least one free cell from the next, calibrated and detected
through the service (``POST /detect``): 50 rectangles. The server is ``sbplan serve`` in a process
of its own, on 127.0.0.1 and a free port, as deployed.

The load: N clients (default 1, 8, 32), each one keep-alive HTTP/1.1 connection posting ``POST
/routes`` one after the other (closed loop: a client sends its next request when the answer came),
on seeded random free start/goal pairs checked beforehand with ``sbplan.plan``. Latency is from
writing the request to reading the whole response. In a closed loop the server is always busy,
so latency is about N times the server's time per request. Paced levels (default 32 clients
sending 5 requests/s each) show the latency at a given offered load instead; there latency
counts from when the request was due, so a late answer that delays the next one is counted. The
clients are plain asyncio streams in this process (on uvloop when installed, each response's head
read at once: 50-100 us of CPU per request, 100-140 us with the default loop and a read per header
line), so that little of the two cores goes to the measuring side; they are real HTTP/1.1
clients over real sockets, parsing the status and Content-Length of every answer. Per level: a warm-up (not counted), then ``--seconds`` of load, repeated
``--repeats`` times; the table gives the median over the repeats of requests/s, p50 and p99, and
the errors (any answer but 201, or a broken connection) summed.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import shapely

import sbplan
from ..detection import calibrate
from ..errors import InputError, PlanningError
from ..planning import load_obstacles
from ..synth import FloorSpec, SceneSpec, render_reference, render_scene

HELP = "the planner service: route requests/s and p50/p99 latency with 1, 8, 32 concurrent clients"
DESCRIPTION = HELP + ". See the module docstring (or docs/benchmarks.md) for the floor and the load."

COLS, ROWS, PITCH_M, RADIUS_M, OBSTACLES = 20, 15, 0.5, 0.15, 50
TARGET_CLIENTS, TARGET_P99_MS = 32, 25.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--clients", default="1,8,32",
                        help="closed loop: concurrent clients per level, each sending when answered (default 1,8,32)")
    parser.add_argument("--paced", default="32x5",
                        help="paced levels: CLIENTSxRATE, each client sending RATE requests/s (default 32x5; '' for none)")
    parser.add_argument("--seconds", type=float, default=3.0, help="measured seconds per level and repeat (default 3)")
    parser.add_argument("--warmup", type=float, default=0.5, help="unmeasured seconds before each (default 0.5)")
    parser.add_argument("--repeats", type=int, default=3, help="repeats per level; medians are reported (default 3)")
    parser.add_argument("--queries", type=int, default=400, help="distinct route queries (default 400)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--planner-processes", type=int, default=None, metavar="N",
                        help="the server's planning processes (default: sbplan serve's, one per core but one)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")


# -- the floor ------------------------------------------------------------------------------------
def floor_images(seed: int):
    """(reference, scene, obstacle cells) of the benchmark's floor: 50 one-cell boxes on cells
    two apart in both directions, so that no two touch."""
    floor = FloorSpec(width=1280, height=960, cols=COLS, rows=ROWS)
    rng = np.random.default_rng([seed, 19])
    sites = [(r, c) for r in range(0, ROWS, 2) for c in range(0, COLS, 2)]
    cells = [sites[i] for i in sorted(rng.choice(len(sites), OBSTACLES, replace=False))]
    centres = floor.centres()
    dx, dy = np.diff(floor.col_x).mean(), np.diff(floor.row_y).mean()
    boxes = []
    for r, c in cells:
        x, y = centres[r, c]
        w, h = 0.36 * dx, 0.36 * dy  # half-sides: the box covers the symbol, not the neighbours'
        boxes.append(np.array([[x - w, y - h], [x + w, y - h], [x + w, y + h], [x - w, y + h]]))
    reference = render_reference(floor, seed=seed)
    scene, _ = render_scene(floor, SceneSpec(obstacles=boxes), seed=seed + 1)
    return reference, scene, cells


def free_queries(obstacles, bounds, n: int, seed: int) -> list[bytes]:
    """n request bodies: seeded start/goal pairs where a robot can stand (farther than its radius
    from every obstacle), at least a third of the floor apart, that sbplan.plan solves."""
    rng = np.random.default_rng([seed, 23])
    x0, y0, x1, y1 = bounds
    span = min(x1 - x0, y1 - y0)
    taken = shapely.union_all(obstacles).buffer(RADIUS_M * 1.05)
    out: list[bytes] = []
    while len(out) < n:
        s, g = rng.uniform((x0 + RADIUS_M, y0 + RADIUS_M), (x1 - RADIUS_M, y1 - RADIUS_M), (2, 2))
        if np.hypot(*(g - s)) < span / 3 or taken.intersects(shapely.MultiPoint([s, g])):
            continue
        try:
            sbplan.plan(obstacles, s, g, robot_radius=RADIUS_M, bounds=bounds)
        except PlanningError:
            continue
        out.append(json.dumps({"start": s.round(4).tolist(), "goal": g.round(4).tolist(),
                               "robot_radius": RADIUS_M}).encode())
    return out


# -- the server -----------------------------------------------------------------------------------
class Server:
    """``sbplan serve -c CALIBRATION --port 0 [extra...]`` in a subprocess (on 127.0.0.1 and a
    free port), started and answering ``/health`` when this returns."""

    def __init__(self, calibration: str | Path, *extra: str, cwd: str | Path | None = None,
                 env: dict | None = None):
        # its log goes to a file: a pipe nobody reads would stop the server once full
        self.log = tempfile.TemporaryFile("w+")
        self.proc = subprocess.Popen([sys.executable, "-m", "sbplan", "serve", "-c", str(calibration), "--port", "0",
                                      *extra], cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=self.log, text=True)
        assert self.proc.stdout is not None  # stdout=PIPE
        line = self.proc.stdout.readline()
        if not line.startswith("sbplan serve: http://"):
            self.proc.kill()
            self.proc.wait()
            self.log.seek(0)
            raise RuntimeError(f"sbplan serve did not start: {line}{self.log.read()}")
        host, port = line.split("http://", 1)[1].split()[0].rsplit(":", 1)
        self.host = host
        self.port = int(port)
        self._wait_until_up()

    def health(self) -> dict:
        status, body = _run(_once(self.host, self.port, "GET", "/health", b""))
        return json.loads(body)

    def _wait_until_up(self, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                status, _ = _run(_once(self.host, self.port, "GET", "/health", b""))
                if status == 200:
                    return
            except OSError:
                time.sleep(0.05)
        raise RuntimeError("sbplan serve did not answer /health")

    def cpu_seconds(self) -> float:
        """User + system CPU time the server process and its child processes (the planning
        processes) used so far."""
        total = 0
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                fields = stat.read_text().rsplit(")", 1)[1].split()
            except OSError:  # a process that just ended
                continue
            if stat.parent.name == str(self.proc.pid) or fields[1] == str(self.proc.pid):
                total += int(fields[11]) + int(fields[12])
        return total / os.sysconf("SC_CLK_TCK")

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self.log.close()


# -- the clients ----------------------------------------------------------------------------------
def _request(method: str, path: str, body: bytes, content_type: str = "application/json") -> bytes:
    head = f"{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: {content_type}\r\n" \
           f"Content-Length: {len(body)}\r\n\r\n"
    return head.encode() + body


async def _exchange(reader, writer, request: bytes) -> tuple[int, bytes]:
    writer.write(request)
    # the status line and the headers in one read (a readline per header cost the measuring
    # side ~20 us of the cores it shares with the server, per request)
    head = await reader.readuntil(b"\r\n\r\n")
    lines = head.split(b"\r\n")
    status = int(lines[0].split()[1])
    length = 0
    for line in lines[1:]:
        if line[:15].lower() == b"content-length:":
            length = int(line[15:])
    return status, await reader.readexactly(length)


def _run(coro):
    """asyncio.run, on uvloop when installed (as the server is): the clients share the two cores
    with the server, and uvloop's streams take about a third less CPU per request."""
    try:
        import uvloop
    except ImportError:
        return asyncio.run(coro)
    return uvloop.run(coro)


async def _once(host: str, port: int, method: str, path: str, body: bytes,
                content_type: str = "application/json") -> tuple[int, bytes]:
    reader, writer = await asyncio.open_connection(host, port)
    try:
        return await _exchange(reader, writer, _request(method, path, body, content_type))
    finally:
        writer.close()


async def _load(host: str, port: int, bodies: list[bytes], clients: int, warmup: float, seconds: float,
                offset: int, rate: float | None = None) -> dict:
    """N clients posting routes for ``warmup + seconds``. ``rate`` None: each sends its next
    request when the answer came (closed loop); else each sends ``rate`` requests per second on a
    fixed schedule (random phase), and latency counts from the scheduled time, so that a slow
    answer delaying the next request is not hidden."""
    requests = [_request("POST", "/routes", b) for b in bodies]
    latencies: list[float] = []
    errors = total = 0
    t_start = time.perf_counter()
    measure_from, stop_at = t_start + warmup, t_start + warmup + seconds
    phases = np.random.default_rng([offset, clients]).uniform(0, 1, clients)

    async def one_client(k: int) -> None:
        nonlocal errors, total
        reader, writer = await asyncio.open_connection(host, port)
        i = offset + k * 9973
        due = t_start + (phases[k] / rate if rate else 0.0)
        try:
            while True:
                if rate:
                    await asyncio.sleep(max(due - time.perf_counter(), 0.0))
                    t0, due = due, due + 1.0 / rate
                else:
                    t0 = time.perf_counter()
                if t0 >= stop_at:
                    return
                try:
                    status, _ = await _exchange(reader, writer, requests[i % len(requests)])
                except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError, ValueError, IndexError):
                    errors += t0 >= measure_from
                    writer.close()
                    reader, writer = await asyncio.open_connection(host, port)
                    continue
                t1 = time.perf_counter()
                total += 1
                if t0 >= measure_from:
                    latencies.append(t1 - t0)
                    errors += status != 201
                i += 1
        finally:
            writer.close()

    await asyncio.gather(*(one_client(k) for k in range(clients)))
    lat = np.asarray(latencies) * 1e3
    return {"clients": clients, "rate": rate, "requests": len(lat), "requests_per_s": len(lat) / seconds,
            "p50_ms": float(np.percentile(lat, 50)) if len(lat) else None,
            "p99_ms": float(np.percentile(lat, 99)) if len(lat) else None,
            "max_ms": float(lat.max()) if len(lat) else None, "errors": errors, "answered": total}


def measure(*, clients=(1, 8, 32), paced=((32, 5.0),), seconds: float = 3.0, warmup: float = 0.5,
            repeats: int = 3, queries: int = 400, seed: int = 0, planner_processes: int | None = None,
            progress=None) -> dict:
    """Build the floor, start the server, detect the floor through it, then load it: closed loop
    with each of ``clients``, then each ``(clients, rate)`` of ``paced``."""
    say = progress or (lambda text: None)
    say("rendering and calibrating the floor")
    reference, scene, cells = floor_images(seed)
    with tempfile.TemporaryDirectory(prefix="sbplan-bench-serve-") as tmp:
        cal_path = calibrate(reference, cell_size=PITCH_M).save(Path(tmp) / "calibration.json")
        say("starting sbplan serve")
        extra = () if planner_processes is None else ("--planner-processes", str(planner_processes))
        server = Server(cal_path, "--max-routes", "1024", *extra)
        try:
            png = cv2.imencode(".png", scene)[1].tobytes()
            status, body = _run(_once(server.host, server.port, "POST", "/detect", png, "image/png"))
            if status != 200:
                raise RuntimeError(f"POST /detect answered {status}: {body[:300]!r}")
            (Path(tmp) / "state.json").write_bytes(body)
            detected = json.loads(body)
            if len(detected["obstacles"]) != OBSTACLES:
                raise RuntimeError(f"the floor should show {OBSTACLES} obstacles, detection found "
                                   f"{len(detected['obstacles'])}")
            floor = load_obstacles(Path(tmp) / "state.json")
            say(f"{len(floor.polygons)} obstacles detected; choosing {queries} queries")
            bodies = free_queries(floor.polygons, floor.bounds, queries, seed)
            levels = []
            for n, rate in [(n, None) for n in clients] + list(paced):
                runs = []
                for rep in range(repeats):
                    load0 = os.getloadavg()[0]
                    cpu0 = server.cpu_seconds()
                    run = _run(_load(server.host, server.port, bodies, n, warmup, seconds,
                                            offset=rep * 131, rate=rate))
                    # warm-up included on both sides: CPU over every request answered
                    run["server_cpu_ms_per_request"] = (server.cpu_seconds() - cpu0) * 1e3 / max(run.pop("answered"), 1)
                    run["load_before"] = load0
                    runs.append(run)
                    say(f"{n} clients{f' x {rate:g}/s' if rate else ''}, run {rep + 1}: {run['requests_per_s']:.0f} "
                        f"req/s, p50 {run['p50_ms']:.2f} ms, p99 {run['p99_ms']:.2f} ms, {run['errors']} errors, "
                        f"load {load0:.1f}")
                med = lambda key: statistics.median(r[key] for r in runs)  # noqa: E731
                levels.append({"clients": n, "rate": rate, "requests_per_s": med("requests_per_s"),
                               "p50_ms": med("p50_ms"), "p99_ms": med("p99_ms"),
                               "max_ms": max(r["max_ms"] for r in runs), "errors": sum(r["errors"] for r in runs),
                               "requests": sum(r["requests"] for r in runs),
                               "server_cpu_ms_per_request": med("server_cpu_ms_per_request"),
                               "load_before": med("load_before"), "runs": runs})
        finally:
            server.stop()
    return {"obstacles": OBSTACLES, "grid": [COLS, ROWS], "pitch_m": PITCH_M, "radius_m": RADIUS_M,
            "seconds": seconds, "warmup": warmup, "repeats": repeats, "queries": queries, "seed": seed,
            "cpus": os.cpu_count(), "load_average": list(os.getloadavg()), "levels": levels,
            "python": sys.version.split()[0], "event_loop": _loop_kind(),
            "planner_processes": "default (one per core but one)" if planner_processes is None else planner_processes}


def _loop_kind() -> str:
    try:
        import uvloop  # noqa: F401
        loop = "uvloop"
    except ImportError:
        loop = "asyncio"
    try:
        import httptools  # noqa: F401
        http = "httptools"
    except ImportError:
        http = "h11"
    return f"{loop} + {http}"


def format_table(result: dict) -> str:
    lines = [f"{result['obstacles']} obstacles on a {result['grid'][0]} x {result['grid'][1]} grid "
             f"(pitch {result['pitch_m']} m), radius {result['radius_m']} m, {result['queries']} queries, seed "
             f"{result['seed']}; {result['seconds']} s per run after {result['warmup']} s warm-up, median of "
             f"{result['repeats']} runs; server: uvicorn ({result['event_loop']}), planning processes: "
             f"{result['planner_processes']}, Python {result['python']}, {result['cpus']} CPUs",
             "",
             f"{'clients':>7} {'each sends':>13} {'requests/s':>11} {'p50 ms':>8} {'p99 ms':>8} {'max ms':>8} "
             f"{'errors':>7} {'requests':>9} {'server CPU ms/req':>18} {'load':>5}",
             "-" * 102]
    for lv in result["levels"]:
        pace = f"{lv['rate']:g}/s" if lv["rate"] else "when answered"
        lines.append(f"{lv['clients']:>7} {pace:>13} {lv['requests_per_s']:>11.0f} {lv['p50_ms']:>8.2f} "
                     f"{lv['p99_ms']:>8.2f} {lv['max_ms']:>8.2f} {lv['errors']:>7} {lv['requests']:>9} "
                     f"{lv['server_cpu_ms_per_request']:>18.3f} {lv['load_before']:>5.1f}")
    lines.append("(load: the machine's 1-minute load average before the runs, median)")
    target = next((lv for lv in result["levels"] if lv["clients"] == TARGET_CLIENTS and not lv["rate"]), None)
    if target is not None:
        met = target["p99_ms"] <= TARGET_P99_MS and target["errors"] == 0
        lines += ["", f"target: {TARGET_CLIENTS} clients, p99 <= {TARGET_P99_MS:g} ms, 0 errors: "
                      f"p99 {target['p99_ms']:.2f} ms, {target['errors']} errors: {'met' if met else 'MISSED'}"]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    try:
        clients = tuple(int(v) for v in args.clients.split(","))
    except ValueError:
        raise InputError(f"--clients: expected numbers separated by commas, got {args.clients!r}") from None
    try:
        paced = tuple((int(n), float(r)) for n, r in (p.split("x") for p in args.paced.split(",") if p))
    except ValueError:
        raise InputError(f"--paced: expected CLIENTSxRATE[,...], got {args.paced!r}") from None
    if (not clients or min(clients) < 1 or args.seconds <= 0 or args.repeats < 1 or args.queries < 1
            or any(n < 1 or not r > 0 for n, r in paced)):
        raise InputError("--clients, --paced, --seconds, --repeats and --queries must be positive")
    result = measure(clients=clients, paced=paced, seconds=args.seconds, warmup=args.warmup, repeats=args.repeats,
                     queries=args.queries, seed=args.seed, planner_processes=args.planner_processes,
                     # on stderr with --json too: stdout carries only the results
                     progress=lambda text: print(f"  {text}", file=sys.stderr, flush=True))
    print(json.dumps(result, indent=2) if args.json else format_table(result))
    return 0
