"""The HTTP and WebSocket API of one workspace (FastAPI), see docs/robots.md.

``create_app(service, token=..., source=...)`` builds the ASGI application; :mod:`.server` runs it
on uvicorn. In front of FastAPI, :class:`Guard` checks the bearer token and the body size of every
request before anything is parsed. Handlers only read the service's immutable state or wait for
its threads (:mod:`.core`): nothing CPU-heavy runs on the event loop.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import logging
import time
from typing import Any, Sequence

from fastapi import FastAPI, Path, Query, Request, WebSocket
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel, ValidationError
from starlette.datastructures import UploadFile
from starlette.exceptions import HTTPException as StarletteHTTPException

from .. import __version__
from ..detection.exports import encode_nav2_image, geojson, nav2_map, nav2_yaml
from ..errors import ImageError, SbplanError
from . import models
from .core import Service
from .errors import PayloadTooLargeError, UnsupportedMediaError, status_and_code
from .events import Broker, serve_client
from .sources import FrameSource, SourceRunner

log = logging.getLogger("sbplan.service")

#: Content types POST /detect takes as the raw body.
IMAGE_TYPES = ("image/png", "image/jpeg", "application/octet-stream")
_ERRORS: dict[int | str, dict[str, Any]] = {
    status: {"model": models.Error, "description": text} for status, text in (
        (400, "malformed JSON"), (401, "missing or wrong bearer token"), (404, "unknown route"),
        (409, "no frame yet, or the camera moved beyond what registration compensates"),
        (413, "body or image too large"), (415, "not a PNG or JPEG image"),
        (422, "invalid request, or no route (start-in-obstacle, goal-in-obstacle, out-of-bounds, no-route)"))}
_ROUTE_ID = Path(pattern=r"^r[0-9]+$", max_length=24, description="the route's id, as POST /routes gave it")


class GeoJSONResponse(JSONResponse):
    media_type = "application/geo+json"


def create_app(service: Service, *, token: str | None = None, source: FrameSource | None = None) -> Any:
    """The ASGI application serving ``service``.

    Parameters
    ----------
    service : Service
    token : str or None
        When given, every request but ``GET /health`` needs ``Authorization: Bearer TOKEN``.
    source : FrameSource or None
        A live source, read from when the application starts and stopped when it stops.
    """

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI):
        broker = Broker(asyncio.get_running_loop())
        app.state.broker = broker
        service.add_listener(broker.listener)
        runner = SourceRunner(service, source).start() if source is not None else None
        try:
            yield
        finally:
            if runner is not None:
                await asyncio.to_thread(runner.stop)
            service.remove_listener(broker.listener)
            broker.close_all()

    app = FastAPI(title="sbplan", version=__version__, lifespan=lifespan,
                  summary="Obstacles seen by a ceiling camera over a floor of reference symbols, and routes around them.",
                  description="Coordinates: `*_m` world metres (x right along the grid's columns, y up: REP-103, "
                              "nav2), `*_px` pixels of the calibration image. Errors: JSON `{code, message}`. "
                              "WebSocket `/events`: see `GET /events/schema` and docs/robots.md.")
    _error_handlers(app)

    @app.get("/health", response_model=models.Health, tags=["service"])
    async def health(request: Request) -> models.Health:
        """Alive, and what it holds. Needs no token."""
        st = service.state
        return models.Health(version=__version__, frame=None if st.snapshot is None else st.snapshot.frame,
                             routes=len(st.routes), clients=len(request.app.state.broker.subscribers),
                             source=service.source_name, auth=token is not None)

    @app.get("/state", response_model=models.State, responses=_ERRORS, tags=["floor"])
    async def state() -> models.State:
        """The current detection: cells, obstacles (outlines and MARs in pixels and metres), the
        camera's movement, frame number and age."""
        snap = service.snapshot()
        assert snap.model is not None  # a published snapshot has its model
        return snap.model.model_copy(update={"age_s": time.time() - snap.received})

    @app.get("/obstacles.geojson", response_model=models.FeatureCollection, response_class=GeoJSONResponse,
             response_model_exclude_none=True, responses=_ERRORS, tags=["floor"])
    async def obstacles(response: Response) -> Any:
        """The current obstacles as GeoJSON (the outline of each, and what the service plans around
        under its obstacle model): WGS84 longitude/latitude when the calibration's workspace is
        georeferenced, else the floor's local metres."""
        snap = service.snapshot()
        response.headers["X-Sbplan-Frame"] = str(snap.frame)
        return await _cached(snap, "geojson", lambda: models.FeatureCollection.model_validate(
            geojson(snap.detection, service.use)))

    @app.get("/map.yaml", response_class=Response, responses={200: {"content": {"text/yaml": {}}}, **_ERRORS},
             tags=["floor"])
    async def map_yaml() -> Response:
        """The ROS 2 nav2 map_server YAML of what the service plans around (its image: GET /map.pgm)."""
        snap = service.snapshot()
        _, meta = await _cached(snap, "nav2", lambda: nav2_map(snap.detection, model=service.use))
        return Response(nav2_yaml(meta), media_type="text/yaml", headers={"X-Sbplan-Frame": str(snap.frame)})

    @app.get("/map.pgm", response_class=Response,
             responses={200: {"content": {"image/x-portable-graymap": {}}}, **_ERRORS}, tags=["floor"])
    async def map_pgm() -> Response:
        """The nav2 map image: 0 occupied, 254 free, 205 unknown (beyond the floor); row 0 is the top
        (largest y)."""
        snap = service.snapshot()
        image, _ = await _cached(snap, "nav2", lambda: nav2_map(snap.detection, model=service.use))
        pgm = await _cached(snap, "pgm", lambda: encode_nav2_image("map.pgm", image))
        return Response(pgm, media_type="image/x-portable-graymap", headers={"X-Sbplan-Frame": str(snap.frame)})

    @app.post("/detect", response_model=models.Detected, responses=_ERRORS, tags=["floor"], openapi_extra={
        "requestBody": {"required": True, "content": {
            "image/png": {"schema": {"type": "string", "format": "binary"}},
            "image/jpeg": {"schema": {"type": "string", "format": "binary"}},
            "multipart/form-data": {"schema": {"type": "object", "required": ["image"], "properties": {
                "image": {"type": "string", "format": "binary"}}}}}}})
    async def detect(request: Request) -> models.Detected:
        """Detect a frame (PNG or JPEG body, or multipart field `image`) and make it the current
        state; routes its new obstacles block are replanned and pushed."""
        data = await _image_body(request, service)
        snap, replanned = await service.detect(data)
        assert snap.model is not None  # a published snapshot has its model
        fields = {k: v for k, v in snap.model if k != "age_s"}
        return models.Detected.model_construct(**fields, routes_replanned=replanned)

    @app.post("/routes", response_model=models.Route, status_code=201, responses=_ERRORS, tags=["routes"],
              openapi_extra=_json_body(models.RouteRequest))
    async def create_route(request: Request) -> Response:
        """Plan a route on the current obstacles (exact shortest route for a disc robot)."""
        # Answered by Guard._create_route before FastAPI sees the request (the hot path: robots
        # ask for routes); this route only documents it in the OpenAPI schema.
        raise AssertionError("POST /routes is answered by the Guard in front of the application")

    @app.get("/routes", response_model=models.RouteList, responses=_ERRORS, tags=["routes"])
    async def list_routes(owner: models.Owner | None = Query(None, description="only this owner's")) -> models.RouteList:
        """The routes kept, least recently changed first."""
        return models.RouteList(routes=[r.model for r in service.state.routes.values()
                                        if owner is None or r.owner == owner])

    @app.get("/routes/{route_id}", response_model=models.Route, responses=_ERRORS, tags=["routes"])
    async def get_route(route_id: str = _ROUTE_ID) -> models.Route:
        return service.route(route_id).model

    @app.post("/routes/{route_id}/replan", response_model=models.Route, responses=_ERRORS, tags=["routes"])
    async def replan_route(request: models.ReplanRequest, route_id: str = _ROUTE_ID) -> models.Route:
        """A new route from the robot's position, around the current obstacles, this route's
        earlier extra obstacles and the new one."""
        return await service.replan_route(route_id, request)

    @app.delete("/routes/{route_id}", response_model=models.Deleted, responses=_ERRORS, tags=["routes"])
    async def delete_route(route_id: str = _ROUTE_ID) -> models.Deleted:
        await service.delete_route(route_id)
        return models.Deleted(id=route_id)

    event_schema = models.events_schema()

    @app.get("/events/schema", response_model=dict, tags=["events"])
    async def events_schema() -> dict:
        """JSON schema of the messages WS /events sends (a union on `type`)."""
        return event_schema

    @app.websocket("/events")
    async def events(ws: WebSocket, owner: models.Owner | None = Query(None)) -> None:
        await serve_client(ws, service, ws.app.state.broker, owner)

    _document_auth(app)
    return Guard(app, token=token, max_body=service.limits.max_body, max_json=service.limits.max_json,
                 service=service)


def _json_body(model: type[BaseModel]) -> dict:
    """OpenAPI for a JSON body a handler parses itself (POST /routes: Guard._create_route)."""
    return {"requestBody": {"required": True, "content": {"application/json": {
        "schema": {"$ref": f"#/components/schemas/{model.__name__}"}}}}}


def _body_errors(exc: ValidationError) -> list[dict]:
    return [{**e, "loc": ("body", *e.get("loc", ()))} for e in exc.errors(include_url=False)]


async def _cached(snap: Any, key: str, make: Any) -> Any:
    """An export of the snapshot, made once on a worker thread (two requests racing both make
    it, and store the same value)."""
    value = snap.cache.get(key)
    if value is None:
        value = snap.cache[key] = await asyncio.to_thread(make)
    return value


async def _image_body(request: Request, service: Service) -> bytes:
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if ctype == "multipart/form-data":
        async with request.form(max_files=1, max_fields=8, max_part_size=service.limits.max_json) as form:
            field = form.get("image")
            if not isinstance(field, UploadFile):
                raise ImageError("image: the multipart body has no file field 'image'")
            data = await field.read()
    elif ctype in IMAGE_TYPES or not ctype:
        data = await request.body()
    else:
        raise UnsupportedMediaError(f"content type {ctype!r}: send a PNG or JPEG as the body (image/png, "
                                    f"image/jpeg) or as the multipart field 'image'")
    if not data:
        raise ImageError("image: the body is empty")
    return data


# -- errors ---------------------------------------------------------------------------------------
def _error(status: int, code: str, message: str, **extra: Any) -> JSONResponse:
    return JSONResponse(models.Error(code=code, message=message, **extra).model_dump(exclude_none=True),
                        status_code=status)


def _sbplan_error(exc: SbplanError) -> tuple[int, models.Error]:
    """The status and the body an SbplanError is answered with."""
    status, code = status_and_code(exc)
    return status, models.Error(code=code, message=str(exc))


#: A bug's answer: the log gets the traceback, the client one line.
_INTERNAL = models.Error(code="internal-error", message="internal error; the server's log has the details")


def _invalid(errors: Sequence[Any]) -> tuple[int, models.Error]:
    """A request that failed validation (FastAPI's error list): 400 malformed JSON, else 422."""
    bad_json = [e for e in errors if e.get("type") == "json_invalid"]
    if bad_json:
        reason = (bad_json[0].get("ctx") or {}).get("error", "")
        return 400, models.Error(code="malformed-json", message=f"the body is not valid JSON{': ' + reason if reason else ''}")
    listed = [{"loc": [str(p) for p in e.get("loc", ())], "msg": e.get("msg", ""), "type": e.get("type", "")}
              for e in errors]
    message = "; ".join(f"{'.'.join(e['loc']) or 'request'}: {e['msg']}" for e in listed[:3])
    if len(listed) > 3:
        message += f"; and {len(listed) - 3} more"
    return 422, models.Error(code="invalid-request", message=message, errors=listed)


def _error_handlers(app: FastAPI) -> None:
    @app.exception_handler(SbplanError)
    async def sbplan_error(request: Request, exc: SbplanError) -> JSONResponse:
        status, error = _sbplan_error(exc)
        return JSONResponse(error.model_dump(exclude_none=True), status_code=status)

    @app.exception_handler(RequestValidationError)
    async def invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        status, error = _invalid(exc.errors())
        return JSONResponse(error.model_dump(exclude_none=True), status_code=status)

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        codes = {404: "not-found", 405: "method-not-allowed"}
        return _error(exc.status_code, codes.get(exc.status_code, f"http-{exc.status_code}"), str(exc.detail))

    @app.exception_handler(Exception)
    async def internal(request: Request, exc: Exception) -> JSONResponse:
        # a bug: the log gets the traceback, the client one line
        log.error("%s %s failed", request.method, request.url.path, exc_info=exc)
        return JSONResponse(_INTERNAL.model_dump(exclude_none=True), status_code=500)


def _document_auth(app: FastAPI) -> None:
    """Say in the OpenAPI document that everything but /health takes a bearer token."""
    original = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = original()
            # models of the bodies handlers parse themselves (_json_body)
            schemas = schema.setdefault("components", {}).setdefault("schemas", {})
            for model in (models.RouteRequest,):
                schemas.setdefault(model.__name__, model.model_json_schema(ref_template="#/components/schemas/{model}"))
            schema.setdefault("components", {}).setdefault("securitySchemes", {})["bearer"] = {
                "type": "http", "scheme": "bearer",
                "description": "required for everything but /health when the service listens beyond "
                               "this machine (sbplan serve --host ... --token / SBPLAN_TOKEN)"}
            for path, ops in schema.get("paths", {}).items():
                if path != "/health":
                    for op in ops.values():
                        op["security"] = [{"bearer": []}]
        assert app.openapi_schema is not None  # FastAPI's openapi() keeps what it made
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]  # FastAPI's documented way to extend the schema


# -- guard ----------------------------------------------------------------------------------------
class Guard:
    """ASGI middleware in front of the application: the bearer token (everything but /health)
    and the body size (``Content-Length`` checked first, then the bytes as they arrive), before
    FastAPI reads or parses anything."""

    def __init__(self, app: FastAPI, *, token: str | None, max_body: int, max_json: int, service: Service):
        self.app, self.token = app, token
        self.max_body, self.max_json = max_body, max_json
        self.service = service

    def __getattr__(self, name: str) -> Any:
        return getattr(self.app, name)  # app.state, app.openapi(), ... for callers holding the guard

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        kind = scope["type"]
        if kind not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        if self.token is not None and scope["path"] != "/health":
            problem = self._auth_problem(scope)
            if problem is not None:
                return await self._deny(scope, receive, send, problem)
        if kind == "websocket":
            return await self.app(scope, receive, send)
        limit = self.max_body if scope["path"] == "/detect" else self.max_json
        length = _header(scope, b"content-length")
        if length is not None:
            if not length.isdigit():
                return await _send_json(send, 400, models.Error(code="bad-request", message="Content-Length is not a number"))
            if int(length) > limit:
                return await _send_json(send, 413, _too_large(limit, int(length)))
        if scope["path"] == "/routes" and scope["method"] == "POST":
            return await self._create_route(receive, send, limit)
        seen = 0

        async def counted() -> dict:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    raise PayloadTooLargeError(_too_large(limit).message, code="body-too-large")
            return message

        await self.app(scope, counted, send)

    async def _create_route(self, receive: Any, send: Any, limit: int) -> None:
        """POST /routes, the hot path (robots ask for routes), answered here without FastAPI's
        routing, dependencies and responses: on the service benchmark they cost ~1 ms of CPU per
        request, more than the planning. The FastAPI route only documents it; the body is
        validated by the model, errors are answered as the handlers answer them."""
        chunks = []
        seen = 0
        while True:
            message = await receive()
            if message["type"] != "http.request":
                return  # the client went away
            chunk = message.get("body", b"")
            seen += len(chunk)
            if seen > limit:
                return await _send_json(send, 413, _too_large(limit))
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        try:
            route = await self.service.create_route(models.RouteRequest.model_validate_json(b"".join(chunks)))
        except ValidationError as exc:
            return await _send_json(send, *_invalid(_body_errors(exc)))
        except SbplanError as exc:
            return await _send_json(send, *_sbplan_error(exc))
        except Exception:
            log.exception("POST /routes failed")
            return await _send_json(send, 500, _INTERNAL)
        body = route.model_dump_json().encode()
        await send({"type": "http.response.start", "status": 201,
                    "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]})
        await send({"type": "http.response.body", "body": body})

    def _auth_problem(self, scope: dict) -> str | None:
        value = _header(scope, b"authorization")
        if value is None:
            return "this service needs a bearer token: send the header 'Authorization: Bearer TOKEN'"
        scheme, _, given = value.partition(" ")
        assert self.token is not None  # asked only when the service has a token
        if scheme.lower() != "bearer" or not hmac.compare_digest(given.strip().encode(), self.token.encode()):
            return "wrong bearer token"
        return None

    async def _deny(self, scope: dict, receive: Any, send: Any, problem: str) -> None:
        body = models.Error(code="unauthorized", message=problem)
        headers = [(b"www-authenticate", b'Bearer realm="sbplan"')]
        if scope["type"] == "http":
            return await _send_json(send, 401, body, headers)
        await receive()  # websocket.connect
        # closing before accepting answers the upgrade with HTTP 403. (An HTTP 401 with a body
        # through the ASGI "websocket.http.response" extension reaches the client too, but
        # uvicorn's websockets protocol then logs an error for every refused connection.)
        await send({"type": "websocket.close", "code": 1008, "reason": problem})


def _too_large(limit: int, length: int | None = None) -> models.Error:
    got = f"{length} bytes" if length is not None else "the body"
    return models.Error(code="body-too-large", message=f"{got} is above this endpoint's limit of {limit} bytes")


def _header(scope: dict, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key == name:
            return value.decode("latin-1")
    return None


async def _send_json(send: Any, status: int, error: models.Error,
                     headers: Sequence[tuple[bytes, bytes]] = ()) -> None:
    body = error.model_dump_json(exclude_none=True).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                            *headers]})
    await send({"type": "http.response.body", "body": body})
