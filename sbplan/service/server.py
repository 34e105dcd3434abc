"""Running the application on uvicorn: in the foreground (``sbplan serve``) or on a thread
(tests, embedding in another program).

The listening socket is bound here, before uvicorn starts, so that port 0 (any free port) can be
used and the actual address printed or returned.
"""

from __future__ import annotations

import gc
import ipaddress
import socket
import threading
import time
from typing import Any

from ..errors import InputError

#: WebSocket messages clients send are small (a position); bigger ones are refused by uvicorn.
WS_MAX_MESSAGE = 64 * 2**10


def is_loopback(host: str) -> bool:
    """Whether ``host`` only listens on this machine (127.0.0.0/8, ::1, localhost)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: a free port)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    # IPPROTO_TCP, not 0: asyncio turns Nagle's algorithm off only on connections of sockets that
    # say so, and with it on, each answer on a kept-alive connection waited ~40 ms for an ACK
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
        sock.listen(2048)
    except OSError as exc:
        sock.close()
        raise InputError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    sock.set_inheritable(True)
    return sock


def address(sock: socket.socket) -> tuple[str, int]:
    host, port = sock.getsockname()[:2]
    return host, port


def freeze_startup_objects() -> None:
    """Move every object alive now (the modules, the application) out of the garbage collector's
    reach (``gc.freeze``), for a process about to serve: a full collection otherwise walks them
    all, and on the service benchmark each one (every few seconds under load) stopped the event
    loop or a planning process for 35-45 ms, the slowest 1 % of the answers. They are freed by
    reference counting as before; only reference cycles among them would stay."""
    gc.collect()
    gc.freeze()


def make_server(app: Any, *, log_level: str = "warning", access_log: bool = False) -> Any:
    """A uvicorn server for ``app`` (uvloop and httptools when installed)."""
    import uvicorn  # the serve extra: the address helpers above work without it

    try:  # on httptools: each response's head and body in one write (see .onewrite)
        from .onewrite import OneWriteProtocol

        http: Any = OneWriteProtocol
    except ImportError:  # no httptools: uvicorn's h11 protocol
        http = "auto"
    config = uvicorn.Config(app, http=http, log_level=log_level, access_log=access_log, lifespan="on",
                            ws_max_size=WS_MAX_MESSAGE, server_header=False, proxy_headers=False,
                            timeout_keep_alive=30, timeout_graceful_shutdown=5)
    return uvicorn.Server(config)


class ServerThread:
    """``app`` served on a thread, on ``host`` and a free port (or ``port``).

    ``with ServerThread(app) as url: ...`` starts it, waits until it accepts connections, and
    stops it at the end; ``url`` is ``http://host:port``.
    """

    def __init__(self, app: Any, *, host: str = "127.0.0.1", port: int = 0, log_level: str = "warning"):
        self.sock = bind(host, port)
        self.host, self.port = address(self.sock)
        self.server = make_server(app, log_level=log_level)
        self._thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.sock]},
                                        name="sbplan-server", daemon=True)

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}"

    def start(self, timeout: float = 30.0) -> str:
        self._thread.start()
        deadline = time.monotonic() + timeout
        while not self.server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise RuntimeError("the server did not start")
            time.sleep(0.01)
        return self.url

    def stop(self, timeout: float = 10.0) -> None:
        self.server.should_exit = True
        self._thread.join(timeout)
        self.sock.close()

    def __enter__(self) -> str:
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()
