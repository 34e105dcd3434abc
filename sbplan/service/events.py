"""WS /events: the service's events fanned out to the connected clients.

Events come from the state thread (:class:`sbplan.service.core.OutEvent`, JSON already made) and
are handed to the event loop; each client has a bounded queue of its own and a task sending from
it, so one slow or vanished client never holds up the others or the service. A client whose queue
fills (it reads slower than events come) is disconnected with close code 1013 rather than
silently losing events: it reconnects and reads ``GET /state`` and ``GET /routes`` to resync.
"""

from __future__ import annotations

import asyncio
import contextlib
from dataclasses import dataclass, field

from pydantic import ValidationError
from starlette.websockets import WebSocket, WebSocketDisconnect

from ..errors import SbplanError
from . import models
from .core import OutEvent, Service
from .errors import status_and_code

#: Close code for a client that fell behind (RFC 6455 "try again later").
TOO_SLOW = 1013
#: Events of these types go only to the route's owner (and to clients without an owner filter).
_ROUTE_EVENTS = frozenset({"route", "route-deleted"})


@dataclass(frozen=True)
class _Close:
    """Put in a client's queue: close the connection with this code and reason."""

    code: int
    reason: str


FELL_BEHIND = _Close(TOO_SLOW, "fell behind the events: reconnect, then GET /state and /routes")
STOPPING = _Close(1001, "the service is stopping")


@dataclass(eq=False)
class Subscriber:
    owner: str | None
    queue: asyncio.Queue = field(default_factory=lambda: asyncio.Queue(Broker.queue_size))


class Broker:
    """The connected clients (event loop thread only, except :meth:`listener`)."""

    queue_size = 1024

    def __init__(self, loop: asyncio.AbstractEventLoop):
        self.loop = loop
        self.subscribers: set[Subscriber] = set()
        self.last_seq = 0

    def listener(self, event: OutEvent) -> None:
        """The service's listener (the state thread, or the event loop itself): hand the event to
        the event loop."""
        with contextlib.suppress(RuntimeError):  # the loop closed: the server is stopping
            self.loop.call_soon_threadsafe(self._dispatch, event)

    def _dispatch(self, event: OutEvent) -> None:
        self.last_seq = max(self.last_seq, event.seq)
        for sub in list(self.subscribers):
            if event.type in _ROUTE_EVENTS and sub.owner is not None and sub.owner != event.owner:
                continue
            self._put(sub, event.text)

    def _put(self, sub: Subscriber, item: str | _Close) -> None:
        try:
            sub.queue.put_nowait(item)
        except asyncio.QueueFull:
            # it fell behind: drop what it has not read and tell its sender to close
            self._close(sub, FELL_BEHIND)

    def _close(self, sub: Subscriber, why: _Close) -> None:
        self.subscribers.discard(sub)
        while not sub.queue.empty():
            sub.queue.get_nowait()
        sub.queue.put_nowait(why)

    def subscribe(self, owner: str | None) -> Subscriber:
        sub = Subscriber(owner)
        self.subscribers.add(sub)
        return sub

    def unsubscribe(self, sub: Subscriber) -> None:
        self.subscribers.discard(sub)

    def close_all(self) -> None:
        """Ask every client's sender to close (server shutdown)."""
        for sub in list(self.subscribers):
            self._close(sub, STOPPING)


async def serve_client(ws: WebSocket, service: Service, broker: Broker, owner: str | None) -> None:
    """One client's connection, until it leaves or falls behind."""
    await ws.accept()
    sub = broker.subscribe(owner)
    try:
        hello = models.HelloEvent(seq=broker.last_seq, frame=_frame(service), owner=owner)
        await ws.send_text(hello.model_dump_json())
        tasks = {asyncio.create_task(_send(ws, sub)), asyncio.create_task(_receive(ws, service, broker, sub))}
        _, pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        for task in pending:
            task.cancel()
        # a receive on a connection that just dropped raises: that is how it ends, not an error
        await asyncio.gather(*tasks, return_exceptions=True)
    except (WebSocketDisconnect, OSError, RuntimeError):
        pass  # the client left while we were greeting it
    finally:
        broker.unsubscribe(sub)


def _frame(service: Service) -> int | None:
    snap = service.state.snapshot
    return None if snap is None else snap.frame


async def _send(ws: WebSocket, sub: Subscriber) -> None:
    while True:
        item = await sub.queue.get()
        try:
            if isinstance(item, _Close):
                await ws.close(item.code, item.reason)
                return
            await ws.send_text(item)
        except (WebSocketDisconnect, OSError, RuntimeError):
            return  # the client is gone (mid-stream disconnects end here)


async def _receive(ws: WebSocket, service: Service, broker: Broker, sub: Subscriber) -> None:
    """Clients may report where their robot is: ``{"type": "position", "route": ID, "position": [x, y]}``."""
    while True:
        message = await ws.receive()
        if message["type"] == "websocket.disconnect":
            return
        text = message.get("text")
        if text is None:
            text = (message.get("bytes") or b"").decode("utf-8", "replace")
        try:
            msg = models.PositionMessage.model_validate_json(text)
            await asyncio.wrap_future(service.set_position(msg.route, msg.position))
        except ValidationError as exc:
            _reply_error(broker, sub, "invalid-message", "expected {\"type\": \"position\", \"route\": ID, "
                         f"\"position\": [x, y]}}: {_first_error(exc)}")
        except SbplanError as exc:  # an unknown route: tell this client, keep the connection
            _reply_error(broker, sub, status_and_code(exc)[1], str(exc))


def _reply_error(broker: Broker, sub: Subscriber, code: str, message: str) -> None:
    broker._put(sub, models.ErrorEvent(seq=broker.last_seq, code=code, message=message).model_dump_json())


def _first_error(exc: ValidationError) -> str:
    err = exc.errors()[0]
    where = ".".join(str(p) for p in err.get("loc", ())) or "message"
    return f"{where}: {err.get('msg', 'invalid')}"
