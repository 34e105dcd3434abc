"""Every request, response and event of the service, as pydantic models.

The OpenAPI document (``/openapi.json``, ``/docs``) is generated from these, and ``GET
/events/schema`` gives the JSON schema of the WebSocket events (:func:`events_schema`, shipped as
``sbplan/schemas/service-events.schema.json``). Coordinates: ``*_m`` are world
metres (x right along the grid's columns, y up toward row 0: ROS REP-103, nav2's frame), ``*_px``
pixels of the calibration image (x right, y down); points are ``[x, y]``; cells ``[row, col]``.
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

#: A finite number: JSON has no NaN or infinity, and a planner cannot use them.
Finite = Annotated[float, Field(allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
XY = tuple[Finite, Finite]
Cell = tuple[int, int]
#: Who a route belongs to: the WebSocket client subscribed with ``?owner=`` gets its updates.
Owner = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.:/-]+$")]


class _Strict(BaseModel):
    """Requests: unknown fields are an error (a misspelt ``robot_radus`` must not be ignored)."""

    model_config = ConfigDict(extra="forbid")


class Error(BaseModel):
    """Every error response."""

    code: str = Field(description="short stable tag: no-frame, start-in-obstacle, not-an-image, too-large, ...")
    message: str = Field(description="one readable line")
    errors: list[dict] | None = Field(default=None, description="invalid-request only: each field's problem")


class Health(BaseModel):
    status: Literal["ok"] = "ok"
    version: str
    frame: int | None = Field(description="number of the current frame; null before the first detection")
    routes: int = Field(description="routes kept")
    clients: int = Field(description="WebSocket clients connected to /events")
    source: str | None = Field(description="the live source, or null when frames are posted")
    auth: bool = Field(description="true when a bearer token is required (everything but /health)")


# -- detection ------------------------------------------------------------------------------------
class ImageSize(BaseModel):
    width: int
    height: int


class GridSize(BaseModel):
    rows: int
    cols: int


class Obstacle(BaseModel):
    id: int
    cells: list[Cell]
    outline_px: list[XY]
    mar_px: list[XY] = Field(description="the minimum-area rectangle, 4 corners")
    centre_px: XY
    size_px: XY = Field(description="[length, width] of the MAR")
    angle_px_deg: float
    outline_m: list[XY] | None = None
    mar_m: list[XY] | None = None
    centre_m: XY | None = None
    size_m: XY | None = None
    angle_m_deg: float | None = None


class GeoreferenceModel(BaseModel):
    latitude_deg: float = Field(description="WGS84 latitude of the world point (0, 0)")
    longitude_deg: float = Field(description="WGS84 longitude of the world point (0, 0)")
    heading_deg: float = Field(description="compass heading of the floor's x axis, degrees clockwise from north")


class WorkspaceInfo(BaseModel):
    bounds_m: tuple[float, float, float, float] = Field(description="[xmin, ymin, xmax, ymax] of the floor")
    pitch_m: XY
    origin_m: XY
    robot_radius_m: float
    frame: str
    # the detection JSON's: /state and POST /detect keep it (a model without it dropped it)
    georeference: GeoreferenceModel | None = Field(None, description="where the floor is on the Earth, if known")


class Camera(BaseModel):
    """The camera's movement since calibration, as this frame showed it."""

    shift_px: XY
    rotation_deg: float
    scale: float
    residual_px: float
    symbols_used: int
    max_movement_px: float
    model: str = Field(description="none, similarity, homography or assumed")
    matrix: list[list[float]] = Field(description="3x3: calibration pixels -> this frame's pixels")
    warning: str | None
    ambiguous_pitch: bool


class DetectionResult(BaseModel):
    """The detection JSON (``sbplan.detection/1``, see docs/detection-json.md)."""

    format: Literal["sbplan.detection/1"]
    image: ImageSize
    grid: GridSize
    symbols_expected: int
    symbols_found: int
    occupied_cells: list[Cell]
    free_cells: int
    obstacles: list[Obstacle]
    workspace: WorkspaceInfo
    camera: Camera
    stages: dict[str, str]
    timings_ms: dict[str, float]


class FrameInfo(BaseModel):
    frame: int = Field(description="frame number, 1 for the first detection, +1 for each one made current")
    received: float = Field(description="when the frame was received, seconds since the epoch")
    source: str = Field(description="'post' for POST /detect, else the live source")
    name: str | None = Field(description="the file name for a folder source")


class Detected(DetectionResult, FrameInfo):
    """POST /detect: the detection, now the current state, and the routes it made replan."""

    routes_replanned: list[str]


class State(DetectionResult, FrameInfo):
    """GET /state: the current detection."""

    age_s: float = Field(description="seconds since the current frame was received")


# -- exports --------------------------------------------------------------------------------------
class PolygonGeometry(BaseModel):
    type: Literal["Polygon"]
    coordinates: list[list[XY]] = Field(description="one ring, counter-clockwise, first point repeated")


class FeatureProperties(BaseModel):
    id: int
    kind: Literal["outline", "mar", "part"] = Field(description="the footprint's outline, or what the planner "
                                                                "avoids under the obstacle model: the MAR or a part")
    cells: list[Cell]
    part: int | None = Field(default=None, description="the part's number (kind part)")


class Feature(BaseModel):
    type: Literal["Feature"]
    geometry: PolygonGeometry
    properties: FeatureProperties


class GeoJSONMeta(BaseModel):
    crs: Literal["WGS84", "local"] = Field(
        description="WGS84: positions are [longitude, latitude] degrees (RFC 7946); local: [x, y] metres of the "
                    "floor's world frame, not longitude and latitude")
    coordinates: str = Field(description="what the positions are, in words")
    frame: str | None = Field(None, description="the local frame (crs local)")
    georeference: GeoreferenceModel | None = Field(None, description="where the floor is on the Earth (crs WGS84)")
    bounds_m: tuple[float, float, float, float] = Field(description="the floor, metres of the local frame")
    obstacle_model: str | None = Field(default=None, description="mar, parts or outline: which features the "
                                                                 "planner avoids")


class FeatureCollection(BaseModel):
    """GET /obstacles.geojson: each obstacle's outline and what the service plans around (its MAR or
    its parts, the obstacle model) (RFC 7946 with a foreign member ``sbplan``; ``sbplan plan
    --obstacles`` reads it): WGS84 longitude/latitude when the calibration's workspace is
    georeferenced, else the floor's local metres (``sbplan.crs``)."""

    type: Literal["FeatureCollection"]
    features: list[Feature]
    sbplan: GeoJSONMeta


# -- routes ---------------------------------------------------------------------------------------
class RouteRequest(_Strict):
    start: XY = Field(description="[x, y] metres")
    goal: XY = Field(description="[x, y] metres")
    robot_radius: NonNegative | None = Field(default=None, description="metres; default: the calibration's workspace radius")
    margin: NonNegative = Field(0.0, description="extra safety distance, metres")
    owner: Owner | None = Field(default=None, description="who to push this route's updates to (WS /events?owner=...)")


class ReplanRequest(_Strict):
    position: XY = Field(description="the robot's current [x, y], metres: the new route starts here")
    obstacle: Annotated[list[XY], Field(min_length=3, max_length=256)] | None = Field(
        None, description="an extra obstacle the robot saw (polygon, metres); kept for this route's later replans")


class PositionMessage(_Strict):
    """A client's message on WS /events: where the robot is now (no replanning; a route a new
    obstacle blocks is replanned from the last position reported)."""

    type: Literal["position"]
    route: str
    position: XY


class Route(BaseModel):
    id: str
    owner: str | None
    version: int = Field(description="1 when created, +1 on every change")
    frame: int = Field(description="the frame whose obstacles this version was planned or checked on")
    state: Literal["ok", "blocked"] = Field(
        description="blocked: a new obstacle blocks the route and no new route was found (see error)")
    reason: Literal["created", "replan", "blocked"] = Field(
        description="why this version exists: created, replan (asked for), blocked (a new obstacle crossed the old one)")
    status: Literal["exact", "approximate"] | None = Field(
        description="approximate: the start or goal had to step out of an obstacle's clearance")
    length_m: float | None
    waypoints_m: list[XY] = Field(description="from position_m to goal_m; empty when blocked")
    start_m: XY
    goal_m: XY
    position_m: XY = Field(description="where this version starts: the start, or the position last reported")
    robot_radius_m: float
    margin_m: float
    extra_obstacles: int = Field(description="obstacles reported with replan requests, kept for this route")
    planner: str
    planning_ms: float
    updated: float = Field(description="seconds since the epoch")
    error: Error | None = None


class RouteList(BaseModel):
    routes: list[Route]


class Deleted(BaseModel):
    id: str
    deleted: Literal[True] = True


# -- events (WS /events) --------------------------------------------------------------------------
class ObstacleSummary(BaseModel):
    id: int
    cells: list[Cell]
    mar_m: list[XY] | None
    outline_m: list[XY] | None


class HelloEvent(BaseModel):
    """First message on every connection: what the client subscribed to and the current frame."""

    type: Literal["hello"] = "hello"
    seq: int = Field(description="events are numbered in the order they happened; a gap means events were missed")
    frame: int | None
    owner: str | None = Field(description="route events are only those of this owner; null: every route")


class DetectionEvent(BaseModel):
    """A new frame became the current state."""

    type: Literal["detection"] = "detection"
    seq: int
    frame: int
    received: float
    source: str
    name: str | None
    occupied_cells: list[Cell]
    obstacles: list[ObstacleSummary]
    camera: Camera
    symbols_found: int
    symbols_expected: int


class RouteEvent(BaseModel):
    """A route was created, replanned on request, or replanned (or found blocked) because a new
    obstacle crossed it."""

    type: Literal["route"] = "route"
    seq: int
    route: Route


class RouteDeletedEvent(BaseModel):
    type: Literal["route-deleted"] = "route-deleted"
    seq: int
    id: str
    owner: str | None


class FrameRejectedEvent(BaseModel):
    """A frame was not made the current state (not an image, camera moved, wrong size)."""

    type: Literal["frame-rejected"] = "frame-rejected"
    seq: int
    source: str
    name: str | None
    code: str
    message: str


class SourceEvent(BaseModel):
    """The live source ended or failed."""

    type: Literal["source"] = "source"
    seq: int
    source: str
    state: Literal["ended", "failed"]
    frames: int = Field(description="frames made current")
    rejected: int = Field(description="frames rejected")
    message: str


class ErrorEvent(BaseModel):
    """Sent to one client whose message could not be used."""

    type: Literal["error"] = "error"
    seq: int
    code: str
    message: str


Event = Annotated[Union[HelloEvent, DetectionEvent, RouteEvent, RouteDeletedEvent, FrameRejectedEvent,
                        SourceEvent, ErrorEvent], Field(discriminator="type")]


def events_schema() -> dict:
    """The JSON Schema (draft 2020-12) of the messages WS /events sends, a union on ``type``: what
    ``GET /events/schema`` serves and ``sbplan/schemas/service-events.schema.json`` ships, for
    clients that check messages without the service at hand (a test keeps the two equal)."""
    return {"$schema": "https://json-schema.org/draft/2020-12/schema",
            "$id": "https://sbplan.invalid/schemas/service-events.schema.json",
            "title": "sbplan serve event (WS /events)",
            "description": "One message of the service's WebSocket /events. Coordinates: *_m world metres (x right "
                           "along the grid's columns, y up toward row 0), *_px pixels of the calibration image; "
                           "cells [row, col].",
            **TypeAdapter(Event).json_schema()}
