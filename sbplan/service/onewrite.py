"""uvicorn's httptools protocol, sending each response's head and the start of its body in one write.

uvicorn writes a response's status line and headers when the application sends
``http.response.start``, and its body on ``http.response.body``: two writes, each a ``send``
system call on uvloop (which writes at once when it can), and two segments for the client to
read. On the service benchmark (32 clients posting routes) those two writes were a quarter of
the event loop's samples (py-spy). :class:`OneWriteProtocol` gives uvicorn's protocol a
transport that keeps back a head announcing a body (``content-length`` above 0) and sends it
with the next write. The bytes on the wire are the same, in the same order.

Only a head can be held, and never for long: it is sent with the body's first part, and at the
latest when the response completes (a HEAD request's body is never written), when the
connection closes (an application failing mid-response), or before a WebSocket upgrade (the
WebSocket protocol gets the plain transport). Imported only when uvicorn runs on httptools
(:func:`sbplan.service.server.make_server`).
"""

from __future__ import annotations

import asyncio
from typing import Any

from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol


#: Body parts up to this size are joined to the held head (a copy); larger ones follow it.
_JOIN_MAX = 1 << 16


def _announces_body(data: bytes) -> bool:
    """Whether ``data`` is a whole response head (as uvicorn writes it: lower-case header names,
    one write) with a Content-Length above 0, i.e. a body write follows."""
    if not (data.startswith(b"HTTP/1.1 ") and data.endswith(b"\r\n\r\n")):
        return False
    at = data.find(b"\r\ncontent-length: ")
    return at >= 0 and data[at + 18:at + 21] != b"0\r\n"


class HeldHeadTransport:
    """A transport that holds a response head (see :func:`_announces_body`) until the next write,
    and sends both at once; everything else is the wrapped transport's."""

    __slots__ = ("transport", "_head")

    def __init__(self, transport: asyncio.Transport):
        self.transport = transport
        self._head: bytes | None = None

    def write(self, data: bytes | bytearray | memoryview) -> None:
        head = self._head
        if head is not None:
            self._head = None
            if len(data) > _JOIN_MAX:  # a large body: not worth copying to save a call
                self.transport.write(head)
                self.transport.write(data)
            else:
                self.transport.write(head + bytes(data))
        elif _announces_body(bytes(data)):
            self._head = bytes(data)
        else:
            self.transport.write(data)

    def writelines(self, chunks: Any) -> None:
        self.write(b"".join(chunks))

    def flush(self) -> None:
        """Send a held head now."""
        head = self._head
        if head is not None:
            self._head = None
            self.transport.write(head)

    def close(self) -> None:
        self.flush()
        self.transport.close()

    def __getattr__(self, name: str) -> Any:  # is_closing, get_extra_info, pause_reading, ...
        return getattr(self.transport, name)


class OneWriteProtocol(HttpToolsProtocol):
    """uvicorn's httptools protocol on a :class:`HeldHeadTransport`."""

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(HeldHeadTransport(transport))  # type: ignore[arg-type]

    def on_response_complete(self) -> None:
        if isinstance(self.transport, HeldHeadTransport):
            self.transport.flush()
        super().on_response_complete()

    def handle_websocket_upgrade(self) -> None:
        held = self.transport
        if isinstance(held, HeldHeadTransport):
            held.flush()
            self.transport = held.transport  # the WebSocket protocol writes its frames itself
        super().handle_websocket_upgrade()
