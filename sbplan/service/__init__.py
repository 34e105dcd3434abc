"""``sbplan serve``: one workspace (a calibration, its current detection, routes) over HTTP and
WebSocket, for robots and fleet software on other machines. Needs the ``serve`` extra.

- :mod:`.core`: :class:`Service`, the state and the threads that change it;
- :mod:`.state`: the immutable state (snapshot of the current detection, route records);
- :mod:`.models`: every request, response and event (pydantic);
- :mod:`.app`: the FastAPI application, the bearer-token and body-size guard;
- :mod:`.events`: WS /events, fanning events out to clients;
- :mod:`.images`: image size from the PNG/JPEG header, before decoding;
- :mod:`.sources`: live sources (a folder of images, until the live package plugs in);
- :mod:`.server`: uvicorn, in the foreground or on a thread.

See docs/robots.md.
"""

from .core import Limits, Service

__all__ = ["Limits", "Service"]
