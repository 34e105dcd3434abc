"""Rendered camera streams: obstacles entering, moving and leaving, a person's shadow passing, the
camera bumped, frames dropped and corrupted, with the truth of every frame.

A :class:`SequenceSpec` is a timeline over scene frames ``0 .. n_frames - 1``; each frame is one
:func:`~sbplan.synth.render_scene` of the obstacles present then, under the sequence's condition:
the lighting and each obstacle's look stay, the sensor noise is new in every frame.
:func:`write_sequence` writes it as a video (MJPG in AVI, through
``cv2.VideoWriter``) or a folder of PNG images, beside ``reference.png`` (the empty floor, for
calibration) and ``truth.jsonl`` (one JSON object per scene frame).

Faults, as a stream shows them:

- ``dropped`` frames are never written: the folder has a gap in its numbering, the video is one
  frame shorter (a constant-rate AVI has no gaps; the truth says which scene frame each video
  frame is);
- ``corrupt`` frames are written undecodable (the video frame's JPEG data zeroed, the PNG file
  cut short): a reader must skip them;
- ``damaged`` frames decode, but a band of random pixels crosses their lower third (a broken
  transfer): one bad frame that the live state must not believe.

Coordinates are floor pixels ``(x, y)``, as everywhere in :mod:`sbplan.synth`.
"""

from __future__ import annotations

import json
import math
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import cv2
import numpy as np
import shapely
from shapely.geometry import Point, Polygon
from shapely import affinity

from ..errors import SceneError
from ..files import write_folder
from ..imageio import write_atomic, write_image
from .floor import FloorSpec, SceneSpec
from .render import _floor, render_reference, render_scene

FORMAT = "sbplan.sequence-truth/1"
#: Output kinds of :func:`write_sequence`.
KINDS = ("avi", "folder")


def _frames(name: str, value: Any) -> tuple[int, ...]:
    try:
        out = tuple(sorted({int(v) for v in value}))
    except (TypeError, ValueError):
        raise SceneError(f"{name}: expected frame numbers, got {value!r}") from None
    return out


@dataclass(frozen=True)
class Track:
    """One obstacle over time.

    Parameters
    ----------
    outline : (K, 2) polygon
        Floor pixels ``(x, y)`` at frame ``first``.
    first, last : int
        The scene frames it is present in, both included.
    velocity : (float, float)
        Pixels per frame it moves by (``(0, 0)``: it stays).
    moving : (int, int) or None
        The frames ``(from, to)`` between which it moves; None: all its frames.
    """

    outline: Any
    first: int
    last: int
    velocity: Any = (0.0, 0.0)
    moving: Any = None

    def __post_init__(self) -> None:
        pts = np.asarray(self.outline, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3 or not np.isfinite(pts).all():
            raise SceneError(f"outline: expected a (K, 2) polygon with K >= 3, got shape {pts.shape}")
        object.__setattr__(self, "outline", tuple(map(tuple, pts.tolist())))
        if int(self.last) < int(self.first):
            raise SceneError(f"first, last: expected first <= last, got {self.first}, {self.last}")
        object.__setattr__(self, "first", int(self.first))
        object.__setattr__(self, "last", int(self.last))
        object.__setattr__(self, "velocity", (float(self.velocity[0]), float(self.velocity[1])))
        if self.moving is not None:
            object.__setattr__(self, "moving", (int(self.moving[0]), int(self.moving[1])))

    def at(self, frame: int) -> np.ndarray | None:
        """The outline ``(K, 2)`` at ``frame``, or None when absent."""
        if not self.first <= frame <= self.last:
            return None
        lo, hi = self.moving if self.moving is not None else (self.first, self.last)
        steps = min(max(frame - lo, 0), hi - lo)
        return np.asarray(self.outline) + np.asarray(self.velocity) * steps


def person_shadow(centre: Any, length: float, angle_deg: float) -> np.ndarray:
    """A person-like shadow outline ``(K, 2)``: an elongated body with a head at one end, ``length``
    pixels long, pointing at ``angle_deg`` (counter-clockwise from +x, as displayed)."""
    body = affinity.scale(Point(0, 0).buffer(1.0, quad_segs=12), 0.36 * length, 0.15 * length)
    head = Point(0.43 * length, 0).buffer(0.085 * length, quad_segs=8)
    shape = affinity.rotate(shapely.union(body, head), -angle_deg, origin=(0, 0))
    assert isinstance(shape, Polygon)  # the head overlaps the body: their union is one polygon
    ring = np.asarray(shape.exterior.coords)[:-1]
    return ring + np.asarray(centre, dtype=np.float64)


@dataclass(frozen=True)
class Shade:
    """A shadow passing over the floor (a person walking by a lamp): no obstacle.

    It moves in a straight line from ``start`` at frame ``first`` to ``end`` at frame ``last``
    (floor pixels), ``length`` pixels long, darkening the floor by ``darkness``.
    """

    start: Any
    end: Any
    first: int
    last: int
    length: float = 120.0
    darkness: float = 0.45
    blur: float = 4.0

    def at(self, frame: int) -> tuple[float, float, tuple[tuple[float, ...], ...]] | None:
        """The shade effect ``(darkness, blur, outline)`` at ``frame``, or None."""
        if not self.first <= frame <= self.last:
            return None
        t = 0.0 if self.last == self.first else (frame - self.first) / (self.last - self.first)
        a, b = np.asarray(self.start, float), np.asarray(self.end, float)
        d = b - a
        angle = math.degrees(math.atan2(-d[1], d[0])) if d.any() else 0.0
        ring = person_shadow(a + t * d, self.length, angle)
        return (float(self.darkness), float(self.blur), tuple(map(tuple, ring.tolist())))


@dataclass(frozen=True)
class SequenceSpec:
    """A timeline of scene frames.

    Parameters
    ----------
    n_frames : int
        Scene frames ``0 .. n_frames - 1``.
    fps : float
        Frames per second of the stream (the video's rate; the folder's names are frame numbers).
    tracks : tuple of Track
    shades : tuple of Shade
    bump : (int, (dx, dy, rotation_deg, scale)) or None
        From this frame on the camera is moved by this much (:class:`~sbplan.synth.Effects` ``motion``).
    dropped, corrupt, damaged : tuple of int
        Scene frames that are not written, written undecodable, or written with a band of noise.
    condition : str
    effects : dict
        Overrides of the condition's effects, for every frame.
    """

    n_frames: int
    fps: float = 10.0
    tracks: tuple = ()
    shades: tuple[Shade, ...] = ()
    bump: Any = None
    dropped: Any = ()
    corrupt: Any = ()
    damaged: Any = ()
    condition: str = "clean"
    effects: Any = field(default_factory=dict)

    def __post_init__(self) -> None:
        s = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        if isinstance(self.n_frames, bool) or not isinstance(self.n_frames, (int, np.integer)) or self.n_frames < 1:
            raise SceneError(f"n_frames: expected an integer >= 1, got {self.n_frames!r}")
        if not (isinstance(self.fps, (int, float)) and 0 < self.fps <= 1000):
            raise SceneError(f"fps: expected a number in (0, 1000], got {self.fps!r}")
        s("tracks", tuple(self.tracks))
        s("shades", tuple(self.shades))
        for name in ("dropped", "corrupt", "damaged"):
            s(name, _frames(name, getattr(self, name)))
        if set(self.corrupt) & set(self.dropped):
            raise SceneError("corrupt, dropped: a frame cannot be both")
        if self.bump is not None:
            frame, motion = self.bump
            s("bump", (int(frame), tuple(float(v) for v in motion)))
        s("effects", dict(self.effects or {}))
        self.scene(0)  # validates condition and effects

    def scene(self, frame: int) -> SceneSpec:
        """The :class:`SceneSpec` of scene frame ``frame``."""
        effects = dict(self.effects)
        if self.bump is not None and frame >= self.bump[0]:
            effects["motion"] = self.bump[1]
        for shade in self.shades:
            now = shade.at(frame)
            if now is not None:
                effects["shade"] = now
        obstacles = [p for p in (t.at(frame) for t in self.tracks) if p is not None]
        return SceneSpec(obstacles=obstacles, condition=self.condition, effects=effects,
                         textures=("noise", "gradient"))

    def to_dict(self) -> dict[str, Any]:
        return {
            "n_frames": int(self.n_frames), "fps": float(self.fps),
            "tracks": [{"outline": [list(p) for p in t.outline], "first": t.first, "last": t.last,
                        "velocity": list(t.velocity), "moving": None if t.moving is None else list(t.moving)}
                       for t in self.tracks],
            "shades": [{"start": list(map(float, h.start)), "end": list(map(float, h.end)), "first": h.first,
                        "last": h.last, "length": h.length, "darkness": h.darkness, "blur": h.blur}
                       for h in self.shades],
            "bump": None if self.bump is None else [self.bump[0], list(self.bump[1])],
            "dropped": list(self.dropped), "corrupt": list(self.corrupt), "damaged": list(self.damaged),
            "condition": self.condition, "effects": {k: v for k, v in self.effects.items()},
        }


def _frame_seed(seed: int, frame: int) -> int:
    return int(np.random.SeedSequence([int(seed), 0x5E0, int(frame)]).generate_state(1)[0])


def _track_cells(floor: FloorSpec, outline: np.ndarray, fraction: float) -> list[list[int]]:
    """Cells ``[row, col]`` whose printed symbol ``outline`` covers more than ``fraction`` of."""
    _, footprints = _floor(floor)
    syms = np.array([Polygon(f[0], f[1:]) for f in footprints], dtype=object)
    cover = shapely.area(shapely.intersection(syms, Polygon(outline))) / shapely.area(syms)
    return [[int(i // floor.cols), int(i % floor.cols)] for i in np.flatnonzero(cover > fraction)]


def render_sequence(floor: FloorSpec, spec: SequenceSpec, *, seed: int = 0) -> Iterator[tuple[int, np.ndarray, dict]]:
    """Every scene frame: ``(frame, image (H, W) uint8, truth dict)``.

    The truth dict holds ``frame``, ``time_ms``, ``cells`` (rows x cols: 1 occupied, 0 free,
    -1 ambiguous), ``tracks`` (index -> occupied cells ``[row, col]`` of each obstacle present),
    ``camera_motion`` (``[dx, dy, rotation_deg, scale]`` or None), ``shade`` (a shadow passes),
    ``dropped``, ``corrupt`` and ``damaged``. Dropped and corrupt frames are rendered too.
    """
    if not isinstance(floor, FloorSpec):
        raise SceneError(f"floor: expected a FloorSpec, got {type(floor).__name__}")
    if not isinstance(spec, SequenceSpec):
        raise SceneError(f"spec: expected a SequenceSpec, got {type(spec).__name__}")
    for k in range(spec.n_frames):
        scene = spec.scene(k)
        # one seed for the whole stream (lighting, each obstacle's look), new noise every frame
        present = [i for i, t in enumerate(spec.tracks) if t.at(k) is not None]
        image, truth = render_scene(floor, scene, seed=seed, noise_seed=_frame_seed(seed, k),
                                    texture_seeds=[seed * 1000 + i for i in present])
        if k in spec.damaged:
            image = _damage(image, _frame_seed(seed, k))
        tracks = {}
        for i, t in enumerate(spec.tracks):
            p = t.at(k)
            if p is not None:
                tracks[str(i)] = _track_cells(floor, p, scene.occupied_fraction)
        effects = scene.resolved_effects()
        yield k, image, {
            "frame": k, "time_ms": k * 1000.0 / spec.fps, "cells": truth.cells.astype(int).tolist(),
            "tracks": tracks, "camera_motion": None if effects.motion is None else list(effects.motion),
            "shade": effects.shade is not None, "dropped": k in spec.dropped, "corrupt": k in spec.corrupt,
            "damaged": k in spec.damaged,
        }


def _damage(image: np.ndarray, seed: int) -> np.ndarray:
    out = image.copy()
    h = out.shape[0]
    y0, y1 = int(h * 0.68), int(h * 0.8)
    out[y0:y1] = np.random.default_rng(seed).integers(0, 256, out[y0:y1].shape, dtype=np.uint8)
    return out


def write_sequence(folder: str | os.PathLike, floor: FloorSpec, spec: SequenceSpec, *, seed: int = 0,
                   kind: str = "avi") -> Path:
    """Write a rendered stream into ``folder``: ``reference.png``, the frames (``sequence.avi`` or
    ``frames/frame-NNNNN.png``), ``truth.jsonl`` (one line per scene frame, see
    :func:`render_sequence`, plus ``"written"``: the frame's index in the video, or its file
    name, or None when dropped) and ``sequence.json`` (the floor and the timeline).

    Returns the path of the stream (the video file or the frames folder).
    """
    if kind not in KINDS:
        raise SceneError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
    # one unit (sbplan.files.write_folder): a video beside another run's truth would score every
    # frame against the wrong answer
    stream = write_folder(folder, lambda tmp: _write_sequence(tmp, floor, spec, seed=seed, kind=kind),
                          names=("reference.png", "sequence.avi", "frames", "truth.jsonl", "sequence.json"))
    return Path(folder) / stream


def _write_sequence(out: Path, floor: FloorSpec, spec: SequenceSpec, *, seed: int, kind: str) -> str:
    write_image(out / "reference.png", render_reference(floor, seed=seed, condition=spec.condition))
    lines = []
    if kind == "avi":
        target = out / "sequence.avi"
        tmp = target.with_name(target.name + ".part.avi")
        writer = cv2.VideoWriter(str(tmp), cv2.CAP_FFMPEG, cv2.VideoWriter.fourcc(*"MJPG"), float(spec.fps),
                                 (floor.width, floor.height), [cv2.VIDEOWRITER_PROP_IS_COLOR, 0])
        if not writer.isOpened():
            raise SceneError(f"{target}: OpenCV cannot write MJPG video here (FFmpeg backend missing?)")
        index, corrupt_at = 0, []
        try:
            for k, image, truth in render_sequence(floor, spec, seed=seed):
                truth["written"] = None
                if not truth["dropped"]:
                    writer.write(image)
                    truth["written"] = index
                    if truth["corrupt"]:
                        corrupt_at.append(index)
                    index += 1
                lines.append(truth)
        finally:
            writer.release()
        if corrupt_at:
            _zero_jpeg_frames(tmp, corrupt_at)
        os.replace(tmp, target)
    else:
        target = out / "frames"
        target.mkdir()
        for k, image, truth in render_sequence(floor, spec, seed=seed):
            name = f"frame-{k:05d}.png"
            truth["written"] = None if truth["dropped"] else name
            if truth["corrupt"]:
                ok, buf = cv2.imencode(".png", image)
                write_atomic(target / name, buf.tobytes()[: len(buf) // 3])  # cut short: undecodable
            elif not truth["dropped"]:
                write_image(target / name, image)
            lines.append(truth)
    write_atomic(out / "truth.jsonl", "".join(json.dumps(t) + "\n" for t in lines), binary=False)
    meta = {"format": FORMAT, "kind": kind, "stream": target.name, "seed": int(seed), "floor": floor.to_dict(),
            "sequence": spec.to_dict()}
    write_atomic(out / "sequence.json", json.dumps(meta, indent=1) + "\n", binary=False)
    return target.name


def _zero_jpeg_frames(path: Path, frames: list[int]) -> None:
    """Zero the JPEG data of the given video frames of an MJPG AVI (RIFF ``00dc`` chunks, in order)."""
    data = bytearray(path.read_bytes())
    chunks, at = [], 0
    while (at := data.find(b"00dc", at)) >= 0:
        size = struct.unpack("<I", data[at + 4:at + 8])[0]
        if data[at + 8:at + 10] == b"\xff\xd8":  # a JPEG frame (not the index's entries)
            chunks.append((at + 8, size))
        at += 4
    for i in frames:
        start, size = chunks[i]
        data[start:start + size] = bytes(size)
    path.write_bytes(bytes(data))


def read_truth(folder: str | os.PathLike) -> list[dict]:
    """The per-frame truth lines :func:`write_sequence` wrote into ``folder``."""
    path = Path(folder) / "truth.jsonl"
    if not path.is_file():
        raise SceneError(f"{path}: no such truth file")
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]


def demo_sequence(floor: FloorSpec, *, n_frames: int = 48, fps: float = 10.0, condition: str = "clean",
                  hysteresis: int = 4) -> SequenceSpec:
    """The standard test stream on ``floor``: everything a live watch meets, placed on its grid.

    - obstacle 0 stands from frame 3 to the end;
    - obstacle 1 shows for ``hysteresis - 2`` frames only (a blip the live state must ignore);
    - obstacle 2 enters at a quarter, slides one pitch to the right, and leaves at three quarters;
    - a person's shadow crosses the floor in ``hysteresis + 2`` frames, early on;
    - the camera is bumped by (4, -3) px and 0.3 degrees at half time;
    - one frame is dropped, one written undecodable and one damaged (a band of noise).

    Obstacles are boxes 0.7 pitch high centred on cells, 0.9 pitch wide (obstacle 0: 2 pitches, two symbols).
    """
    if floor.cols < 4 or floor.rows < 3:
        raise SceneError(f"floor: the demo sequence needs at least 4 x 3 cells, got {floor.cols} x {floor.rows}")
    if n_frames < 24:
        raise SceneError(f"n_frames: the demo sequence needs at least 24 frames, got {n_frames}")
    centres = floor.centres()
    dx, dy = floor.pitch_px

    def box(r: int, c: int, w: float = 0.9, h: float = 0.7) -> np.ndarray:
        x, y = centres[r, c]
        return np.array([[x - w * dx / 2, y - h * dy / 2], [x - w * dx / 2, y + h * dy / 2],
                         [x + w * dx / 2, y + h * dy / 2], [x + w * dx / 2, y - h * dy / 2]])

    q = n_frames // 4
    slide = (q + hysteresis + 2, q + hysteresis + 6)
    tracks = (
        Track(box(0, 0, 2.0), 3, n_frames - 1),
        Track(box(floor.rows - 1, floor.cols - 1), q, q + max(hysteresis - 3, 0)),
        Track(box(floor.rows // 2, 1), q, 3 * q, velocity=(dx / (slide[1] - slide[0]), 0.0), moving=slide),
    )
    h, w = floor.height, floor.width
    shade = Shade(start=(-0.1 * w, 0.55 * h), end=(1.1 * w, 0.35 * h), first=4, last=4 + hysteresis + 1,
                  length=1.3 * dx, darkness=0.45, blur=0.05 * dx)
    return SequenceSpec(n_frames=n_frames, fps=fps, tracks=tracks, shades=(shade,),
                        bump=(n_frames // 2, (4.0, -3.0, 0.3, 1.0)), dropped=(q + 1,), corrupt=(2 * q + 1,),
                        damaged=(2 * q + 3,), condition=condition)
