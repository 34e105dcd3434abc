"""The planner service started for real, for the tests: uvicorn on a thread, on 127.0.0.1 and a
free port, and clients that talk to it over TCP (httpx, websockets)."""

from __future__ import annotations

import contextlib
import json
import time
from pathlib import Path

import cv2
import httpx
import numpy as np
from websockets.sync.client import connect

from sbplan.service import Limits, Service
from sbplan.service.app import create_app
from sbplan.service.server import ServerThread

ROOT = Path(__file__).resolve().parents[1]
MAP = ROOT / "maps" / "paper-8x6"
#: The paper's floor: the reference (empty) and the scene with 3 obstacles over 13 cells.
EMPTY_PNG = (MAP / "reference.png").read_bytes()
SCENE_PNG = (MAP / "scene-01.png").read_bytes()
#: Along row 2 of the paper's floor, from the left edge to the right: free on the empty floor,
#: blocked by two of the scene's obstacles.
START, GOAL = (0.25, 1.75), (3.75, 1.75)


@contextlib.contextmanager
def running(calibration, *, token=None, source=None, limits=Limits(), listeners=(), **options):
    """(url, service) of a service on a free port of 127.0.0.1, stopped at the end; ``listeners``
    get every event from the start."""
    service = Service(calibration, limits=limits, **options)
    for listener in listeners:
        service.add_listener(listener)
    try:
        with ServerThread(create_app(service, token=token, source=source), host="127.0.0.1") as url:
            yield url, service
    finally:
        service.close()


def client(url: str, **kwargs) -> httpx.Client:
    # trust_env=False: a proxy configured in the environment must not see requests to 127.0.0.1
    return httpx.Client(base_url=url, timeout=30, trust_env=False, **kwargs)


def ws_connect(url: str, path: str = "/events", **kwargs):
    return connect(url.replace("http://", "ws://") + path, proxy=None, open_timeout=10, **kwargs)


def receive(ws, *, types=None, timeout: float = 20.0) -> dict:
    """The next event (of one of ``types``), as a dict."""
    deadline = time.monotonic() + timeout
    while True:
        event = json.loads(ws.recv(timeout=max(deadline - time.monotonic(), 0.01)))
        if types is None or event["type"] in types:
            return event


def wait_for(predicate, timeout: float = 20.0, step: float = 0.02):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(step)
    raise AssertionError("condition not reached in time")


def png(image: np.ndarray) -> bytes:
    return cv2.imencode(".png", image)[1].tobytes()


def jpeg(png_bytes: bytes, quality: int = 95) -> bytes:
    image = cv2.imdecode(np.frombuffer(png_bytes, np.uint8), cv2.IMREAD_GRAYSCALE)
    return cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])[1].tobytes()
