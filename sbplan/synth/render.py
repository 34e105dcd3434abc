"""The scene renderer: empty floor (reference) and floors with obstacles, with ground truth.

Model: the floor plane carries a reflectance image (textured floor, dark printed symbols, obstacle
tops drawn over it, all antialiased by 4x4 supersampling). Lighting multiplies it (gain, gradient,
soft cast shadows) and adds glare (highlights); the camera then warps it (tilt, distortion), blurs
it, adds signal-dependent noise, quantizes to 8 bits and optionally JPEG-compresses it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any, Callable, Sequence

import cv2
import numpy as np
import shapely
from shapely.geometry import Polygon

from ..errors import SceneError
from .aruco import aruco_pattern
from ..polygons import apply_homography
from .camera import Camera, moved_view, view_change
from .conditions import Effects, condition_effects
from .floor import FloorSpec, SceneSpec, rings_centroid
from .obstacles import coverage, outline, texture, window
from .truth import AMBIGUOUS, FREE, OCCUPIED, GroundTruth

_REFERENCE_STREAM = 0x5EF  # keeps the reference's noise independent of a scene with the same seed


# -- printed pattern (layout) ------------------------------------------------------------------
def symbol_pattern(floor: FloorSpec) -> tuple[np.ndarray, list[list[np.ndarray]]]:
    """Ink coverage of the symbol grid, and each cell's footprint.

    Returns
    -------
    alpha : ndarray (H, W) float32 in [0, 1]
        Ink coverage in the floor plane.
    footprints : list of list of ndarray
        Per cell in row-major order (``row * cols + col``): the printed shape's rings in floor
        pixels ``(x, y)``, outline first. Ground truth measures occlusion against these.
    """
    template = floor.symbol_rings_px()
    alpha = np.zeros((floor.height, floor.width), np.float32)
    footprints = []
    for y in floor.row_y:
        for x in floor.col_x:
            rings = [r + (x, y) for r in template]
            footprints.append(rings)
            win = window(rings[0], floor.width, floor.height)
            if win is None:
                continue
            x0, y0, w, h = win
            np.maximum(alpha[y0:y0 + h, x0:x0 + w], coverage([rings], x0, y0, w, h),
                       out=alpha[y0:y0 + h, x0:x0 + w])
    return alpha, footprints


#: layout name -> function(floor) -> (ink alpha, per-cell footprints).
PATTERNS: dict[str, Callable[[FloorSpec], tuple[np.ndarray, list]]] = {"symbols": symbol_pattern,
                                                                       "aruco": aruco_pattern}


@functools.lru_cache(maxsize=6)
def _floor(floor: FloorSpec) -> tuple[np.ndarray, tuple]:
    """Reflectance of the empty floor (grey levels, float32, read-only) and the cell footprints."""
    h, w = floor.height, floor.width
    rng = np.random.default_rng(np.random.SeedSequence([floor.floor_seed, 0xF1002]))
    t = floor.texture
    mottle = cv2.resize(rng.standard_normal((max(h // 40, 2), max(w // 40, 2))).astype(np.float32), (w, h),
                        interpolation=cv2.INTER_CUBIC)
    detail = cv2.resize(rng.standard_normal((max(h // 6, 2), max(w // 6, 2))).astype(np.float32), (w, h),
                        interpolation=cv2.INTER_LINEAR)
    grain = rng.standard_normal((h, w), dtype=np.float32)
    tex = t * (0.8 * mottle + 0.4 * detail + 0.35 * grain)
    alpha, footprints = PATTERNS[floor.layout](floor)
    ink = floor.background - floor.contrast
    refl = (floor.background + tex) * (1.0 - alpha) + (ink + 0.3 * tex) * alpha
    refl = np.clip(refl, 0, 255).astype(np.float32)
    refl.setflags(write=False)
    return refl, tuple(footprints)


def _camera(floor: FloorSpec, effects: Effects) -> Camera:
    tilt = floor.tilt if effects.tilt is None else effects.tilt
    dist = floor.distortion if effects.distortion is None else float(effects.distortion)
    return Camera(floor.width, floor.height, tilt, dist)


def _rngs(seed: int, n: int, *tag: int) -> list[np.random.Generator]:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SceneError(f"seed: expected an integer >= 0, got {seed!r}")
    return [np.random.default_rng(s) for s in np.random.SeedSequence([int(seed), *tag]).spawn(n)]


# -- lighting and camera -----------------------------------------------------------------------
def _expose(refl: np.ndarray, effects: Effects, floor: FloorSpec, cam: Camera, rng_light: np.random.Generator,
            rng_noise: np.random.Generator, obstacle_alpha: np.ndarray | None,
            motion: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    h, w = refl.shape
    pitch = float(np.mean(floor.pitch_px))
    draws: dict = {}
    # Draw every lighting variable whether used or not, so that one effect's presence does not
    # change another's draws for the same seed.
    grad_angle = rng_light.uniform(0, 2 * math.pi)
    light_angle = rng_light.uniform(0, 2 * math.pi)
    hl = [(rng_light.uniform(0.1, 0.9) * w, rng_light.uniform(0.1, 0.9) * h, rng_light.uniform(0.35, 0.9) * pitch,
           rng_light.uniform(0.5, 1.0), rng_light.uniform(0, 180)) for _ in range(effects.highlights)]
    illum = None
    if effects.gradient:
        ys, xs = np.ogrid[0:h, 0:w]
        cx, cy = (w - 1) / 2, (h - 1) / 2
        half = 0.5 * (abs(math.cos(grad_angle)) * w + abs(math.sin(grad_angle)) * h)
        ramp = ((xs - cx) * math.cos(grad_angle) + (ys - cy) * math.sin(grad_angle)) / half
        illum = (1.0 + effects.gradient * ramp).astype(np.float32)
        draws["gradient_angle_deg"] = math.degrees(grad_angle)
    if effects.shadows and obstacle_alpha is not None:
        length = 0.14 * pitch
        dx, dy = length * math.cos(light_angle), length * math.sin(light_angle)
        shifted = cv2.warpAffine(obstacle_alpha, np.array([[1, 0, dx], [0, 1, dy]], np.float32), (w, h))
        sigma = 0.07 * pitch
        shadow = cv2.GaussianBlur(np.maximum(shifted, obstacle_alpha), (0, 0), sigma)
        shade = 1.0 - effects.shadows * shadow * (1.0 - obstacle_alpha)
        illum = shade if illum is None else illum * shade
        draws["shadow_offset_px"] = [dx, dy]
        draws["shadow_blur_px"] = sigma
    if effects.shade is not None:
        darkness, blur, ring = effects.shade
        ring = np.asarray(ring)
        win = window(ring, w, h, pad=int(math.ceil(3 * blur)) + 2)
        if win is not None and darkness > 0:
            x0, y0, ww, hh = win
            mask: np.ndarray = np.zeros((h, w), np.float32)
            mask[y0:y0 + hh, x0:x0 + ww] = coverage([[ring]], x0, y0, ww, hh)
            if blur > 0:
                mask = cv2.GaussianBlur(mask, (0, 0), blur)
            shade = 1.0 - darkness * mask
            illum = shade if illum is None else illum * shade
    img = refl * illum if illum is not None else refl.copy()
    if effects.gain != 1.0:
        img *= effects.gain
    if effects.offset:
        img += effects.offset
    if hl:
        draws["highlights"] = []
        glare = np.zeros((h, w), np.float32)
        for (cx, cy, ax, ratio, ang) in hl:
            a = math.radians(ang)
            ys, xs = np.ogrid[0:h, 0:w]
            u = ((xs - cx) * math.cos(a) + (ys - cy) * math.sin(a)) / ax
            v = (-(xs - cx) * math.sin(a) + (ys - cy) * math.cos(a)) / (ax * ratio)
            r2 = u * u + v * v
            # a bright plateau with a soft rim: binarizers see a round blob (the paper's lighting error)
            np.maximum(glare, np.clip((1.0 - r2) * 2.5, 0, 1) ** 1.5, out=glare)
            draws["highlights"].append({"centre_floor_px": [cx, cy], "semi_axes_px": [ax, ax * ratio], "angle_deg": ang})
        img += effects.highlight_strength * glare
    img = cam.warp(img) if motion is None else moved_view(img, cam, motion)
    if effects.blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), effects.blur)
    if effects.noise > 0:
        sigma = effects.noise * np.sqrt((np.clip(img, 0, 255) + 20.0) / 148.0)
        img = img + rng_noise.standard_normal(img.shape, dtype=np.float32) * sigma
    out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    if effects.jpeg:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(effects.jpeg)])
        out = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    return out, draws


# -- public API --------------------------------------------------------------------------------
def render_reference(floor: FloorSpec, *, seed: int = 0, condition: str = "clean",
                     effects: dict | None = None) -> np.ndarray:
    """The empty floor under base lighting, as the fixed camera sees it.

    Parameters
    ----------
    floor : FloorSpec
    seed : int
        Seed of the sensor noise.
    condition : str
        Only the condition's camera geometry (tilt, distortion) is used: the camera is fixed, so
        render the reference with the condition of the scenes it is compared with.
    effects : dict, optional
        Overrides of the base :class:`Effects` (e.g. ``{"noise": 0}``).

    Returns
    -------
    ndarray (H, W) uint8
    """
    if not isinstance(floor, FloorSpec):
        raise SceneError(f"floor: expected a FloorSpec, got {type(floor).__name__}")
    cond = condition_effects(condition)
    base = Effects(tilt=cond.tilt, distortion=cond.distortion)
    if effects:
        try:
            base = dataclasses.replace(base, **effects)
        except TypeError as exc:
            raise SceneError(f"effects: {exc}") from None
    refl, _ = _floor(floor)
    rng_light, rng_noise = _rngs(seed, 2, _REFERENCE_STREAM)
    img, _ = _expose(refl, base, floor, _camera(floor, base), rng_light, rng_noise, None)
    return img


def render_scene(floor: FloorSpec, scene: SceneSpec | None = None, *, seed: int = 1, noise_seed: int | None = None,
                 texture_seeds: list[int] | None = None) -> tuple[np.ndarray, GroundTruth]:
    """A floor with obstacles under the scene's condition, and its ground truth.

    Parameters
    ----------
    floor : FloorSpec
    scene : SceneSpec, optional
        Default ``SceneSpec()`` (three random obstacles, clean).
    seed : int
        Seeds obstacles, textures, lighting draws and sensor noise (independent streams: the same
        seed under another condition gives the same obstacles).
    noise_seed : int, optional
        Seeds the sensor noise instead of ``seed``: frames of a stream keep the seed (the same
        lighting) and draw new noise.
    texture_seeds : list of int, optional
        One per obstacle of ``scene.obstacles``: each obstacle's texture drawn from its own seed,
        so that it looks the same whatever else stands on the floor (frames of a stream).

    Returns
    -------
    image : ndarray (H, W) uint8
    truth : GroundTruth
    """
    if not isinstance(floor, FloorSpec):
        raise SceneError(f"floor: expected a FloorSpec, got {type(floor).__name__}")
    scene = SceneSpec() if scene is None else scene
    if not isinstance(scene, SceneSpec):
        raise SceneError(f"scene: expected a SceneSpec, got {type(scene).__name__}")
    if texture_seeds is not None and (scene.obstacles is None or len(texture_seeds) != len(scene.obstacles)):
        raise SceneError("texture_seeds: give one per obstacle of scene.obstacles")
    effects = scene.resolved_effects()
    cam = _camera(floor, effects)
    # spawned streams do not depend on how many are spawned: the first four are what they were
    # before motion and wear had streams of their own
    r_obs, r_tex, r_light, r_noise, r_motion, r_wear = _rngs(seed, 6)
    if noise_seed is not None:
        r_noise = _rngs(noise_seed, 1, 0x015E)[0]
    polys, kinds = _place_obstacles(floor, scene, r_obs)
    refl0, footprints = _floor(floor)
    refl = refl0.copy()
    if effects.wear:
        _wear(refl, floor, effects.wear, r_wear)
    motion = _motion(floor, effects, seed, r_motion)
    alpha_sum = np.zeros_like(refl)  # the obstacles' coverage, added up
    textures = []
    for i, (poly, kind) in enumerate(zip(polys, kinds)):
        if texture_seeds is not None:
            r_tex = _rngs(int(texture_seeds[i]), 1, 0x7E7)[0]
        name = scene.textures[int(r_tex.integers(len(scene.textures)))]
        textures.append(name)
        win = window(poly, floor.width, floor.height)
        if win is None:
            continue
        x0, y0, w, h = win
        a = coverage([[poly]], x0, y0, w, h)
        centre = poly.mean(axis=0) - (x0, y0)
        size = float(np.ptp(poly, axis=0).max())
        tex = texture(kind, name, (h, w), centre, size, r_tex, contrast=effects.texture_contrast)
        sub = refl[y0:y0 + h, x0:x0 + w]
        sub += (tex - sub) * a
        np.maximum(alpha_sum[y0:y0 + h, x0:x0 + w], a, out=alpha_sum[y0:y0 + h, x0:x0 + w])
    union_alpha = alpha_sum if polys else None
    view = view_change(floor.width, floor.height, motion, effects.sag)
    img, draws = _expose(refl, effects, floor, cam, r_light, r_noise, union_alpha, view)
    truth = _truth(floor, scene, effects, cam, footprints, polys, kinds, textures, seed, draws, motion, view)
    return img, truth


#: A camera movement ``(dx px, dy px, rotation degrees, scale)`` (:attr:`Effects.motion`).
Motion = tuple[float, float, float, float]

#: What ``vibration = 1`` reaches at most: shift (px), rotation (degrees), zoom (fraction).
VIBRATION_LIMITS = (8.0, 0.5, 0.01)
#: Where ``drift = 1`` ends: (dx, dy) px, rotation (degrees), zoom (fraction).
DRIFT_END = (6.0, -3.0, 0.4, 0.008)


def _motion(floor: FloorSpec, effects: Effects, seed: int, rng: np.random.Generator) -> Motion | None:
    """The camera's movement since calibration, ``(dx, dy, rotation_deg, scale)``, or None."""
    dx, dy, rot, scale = effects.motion if effects.motion is not None else (0.0, 0.0, 0.0, 1.0)
    # drawn whatever the effects, so that vibration does not change with drift and back
    r, phi = math.sqrt(rng.uniform()), rng.uniform(0, 2 * math.pi)
    v_rot, v_zoom = rng.uniform(-1, 1), rng.uniform(-1, 1)
    if effects.vibration:
        shift, rmax, zmax = (effects.vibration * v for v in VIBRATION_LIMITS)
        dx, dy = dx + shift * r * math.cos(phi), dy + shift * r * math.sin(phi)
        rot, scale = rot + rmax * v_rot, scale * (1.0 + zmax * v_zoom)
    if effects.drift:
        # the golden ratio spreads consecutive seeds along the path
        t = effects.drift * ((int(seed) * 0.6180339887498949) % 1.0)
        ex, ey, er, ez = DRIFT_END
        dx, dy, rot, scale = dx + t * ex, dy + t * ey, rot + t * er, scale * (1.0 + t * ez)
    if (dx, dy, rot, scale) == (0.0, 0.0, 0.0, 1.0):
        return None
    return dx, dy, rot, scale


def _wear(refl: np.ndarray, floor: FloorSpec, amount: float, rng: np.random.Generator) -> None:
    """Wear ``refl`` (the floor's reflectance, in place): scratches of floor colour across symbols,
    dark dirt specks, and dark tyre marks along the gaps between symbol rows and columns."""
    h, w = refl.shape
    dx, dy = floor.pitch_px
    size = float(floor.symbol_size)
    ink = floor.background - floor.contrast
    centres = floor.centres().reshape(-1, 2)
    aa = 4  # fractional bits of cv2's antialiased drawing

    def stroke(draw: Callable[[np.ndarray], Any]) -> np.ndarray:
        alpha = np.zeros((h, w), np.float32)
        draw(alpha)
        return np.clip(alpha, 0, 1)

    def pt(p: Sequence[float] | np.ndarray) -> tuple[int, int]:
        return int(round(p[0] * (1 << aa))), int(round(p[1] * (1 << aa)))

    # scratches: straight strokes of bare floor, 1-3 px wide, through about half of the symbols
    n = int(round(amount * 0.5 * len(centres)))
    for i in rng.choice(len(centres), size=min(n, len(centres)), replace=False):
        a = rng.uniform(0, math.pi)
        half = rng.uniform(0.3, 0.6) * size
        mid = centres[i] + rng.uniform(-0.2, 0.2, 2) * size
        d = np.array([math.cos(a), math.sin(a)]) * half
        width = int(rng.integers(1, 4))
        alpha = stroke(lambda m: cv2.line(m, pt(mid - d), pt(mid + d), 1.0, width, cv2.LINE_AA, aa))
        refl += (floor.background - refl) * alpha
    # dirt specks: small dark dots anywhere, some on symbols' edges
    n = int(round(amount * 2 * len(centres)))
    alpha = np.zeros((h, w), np.float32)
    for _ in range(n):
        near = centres[int(rng.integers(len(centres)))] + rng.uniform(-0.5, 0.5, 2) * (dx, dy)
        cv2.circle(alpha, pt(near), int(round(rng.uniform(0.5, 1.5) * (1 << aa))), 1.0, -1, cv2.LINE_AA, aa)
    refl += (ink - refl) * np.clip(alpha, 0, 1) * 0.8
    # tyre marks: long smooth dark bands, 4-10 px wide, 20-45 % darker, along the gaps between symbols
    gap_x = [c + dx / 2 for c in floor.col_x[:-1]]
    gap_y = [r + dy / 2 for r in floor.row_y[:-1]]
    n = int(round(amount * 3))
    for _ in range(n):
        if not gap_x and not gap_y:
            break
        horizontal = bool(rng.integers(2)) if gap_x and gap_y else bool(gap_y)
        gaps = gap_y if horizontal else gap_x
        at = gaps[int(rng.integers(len(gaps)))]
        length = w if horizontal else h
        t = np.linspace(0, length, 64)
        wobble = 0.12 * (dy if horizontal else dx) * np.sin(t / length * rng.uniform(1, 3) * math.pi + rng.uniform(0, 6))
        pts = np.c_[t, at + wobble] if horizontal else np.c_[at + wobble, t]
        width = int(rng.integers(4, 11))
        alpha = stroke(lambda m: cv2.polylines(m, [np.rint(pts * (1 << aa)).astype(np.int32)], False, 1.0, width,
                                               cv2.LINE_AA, aa))
        refl *= 1.0 - rng.uniform(0.2, 0.45) * alpha


def _place_obstacles(floor: FloorSpec, scene: SceneSpec,
                     rng: np.random.Generator) -> tuple[list[np.ndarray], list[str]]:
    if scene.obstacles is not None:
        given = [np.asarray(o, dtype=np.float64) for o in scene.obstacles]
        for i, p in enumerate(given):
            if not Polygon(p).is_valid:
                raise SceneError(f"obstacles[{i}]: not a valid simple polygon")
        return given, ["polygon"] * len(given)
    dx, dy = floor.pitch_px
    pitch = 0.5 * (dx + dy)
    lo_x, hi_x = floor.col_x[0] - dx / 2, floor.col_x[-1] + dx / 2
    lo_y, hi_y = floor.row_y[0] - dy / 2, floor.row_y[-1] + dy / 2
    polys: list[np.ndarray] = []
    kinds: list[str] = []
    shapes: list[Polygon] = []
    for _ in range(scene.n_obstacles):
        kind = scene.kinds[int(rng.integers(len(scene.kinds)))]
        best = None
        for _try in range(60):
            size = rng.uniform(*scene.size) * pitch
            centre = np.array([rng.uniform(lo_x, hi_x), rng.uniform(lo_y, hi_y)])
            p = outline(kind, centre, size, rng)
            if p[:, 0].min() < 1 or p[:, 1].min() < 1 or p[:, 0].max() > floor.width - 2 or p[:, 1].max() > floor.height - 2:
                continue
            shp = Polygon(p)
            gap = min((shp.distance(s) for s in shapes), default=math.inf)
            if best is None or gap > best[0]:
                best = (gap, p, shp)
            if gap >= scene.min_gap:
                break
        if best is None:
            raise SceneError(f"size: obstacles of {scene.size} pitches do not fit the {floor.width} x {floor.height} image")
        polys.append(best[1])
        shapes.append(best[2])
        kinds.append(kind)
    return polys, kinds


def _densify(p: np.ndarray, step: float) -> np.ndarray:
    nxt = np.roll(p, -1, axis=0)
    n = np.maximum(np.ceil(np.linalg.norm(nxt - p, axis=1) / step).astype(int), 1)
    return np.concatenate([p[i] + (nxt[i] - p[i]) * (np.arange(n[i])[:, None] / n[i]) for i in range(len(p))])


def _truth(floor: FloorSpec, scene: SceneSpec, effects: Effects, cam: Camera, footprints: tuple[np.ndarray, ...],
           polys: list[np.ndarray], kinds: list[str], textures: list[str], seed: int, draws: dict[str, Any],
           motion: Motion | None, view: np.ndarray | None) -> GroundTruth:
    rows, cols = floor.rows, floor.cols
    syms = np.array([Polygon(f[0], f[1:]) for f in footprints], dtype=object)
    overlap = np.zeros(len(syms))
    near = np.zeros(len(syms), bool)
    if polys:
        union = shapely.union_all([Polygon(p) for p in polys])
        shapely.prepare(union)
        overlap = shapely.area(shapely.intersection(syms, union)) / shapely.area(syms)
        near = shapely.distance(syms, union) <= scene.near_px
    cells = np.full(len(syms), FREE, np.int8)
    cells[overlap > scene.occupied_fraction] = OCCUPIED
    cells[(overlap <= scene.occupied_fraction) & ((overlap > 0) | near)] = AMBIGUOUS
    if cam.identity:
        centres = floor.centres().reshape(-1, 2).copy()
        obstacles = [p.copy() for p in polys]
    else:
        template = floor.symbol_rings_px()
        dense = [_densify(r, 1.0) for r in template]
        centres = np.empty((len(footprints), 2))
        grid = floor.centres().reshape(-1, 2)
        for i, c in enumerate(grid):
            centres[i], _ = rings_centroid([cam.floor_to_image(r + c) for r in dense])
        obstacles = [cam.floor_to_image(_densify(p, 3.0)) for p in polys]
    camera = {"tilt_deg": list(cam.tilt), "distortion_k1": cam.distortion, "homography": cam.h.tolist()}
    if view is not None:
        centres = apply_homography(view, centres)
        obstacles = [apply_homography(view, p) for p in obstacles]
        dx, dy, rot, scale = motion if motion is not None else (0.0, 0.0, 0.0, 1.0)
        camera["motion"] = {"shift_px": [dx, dy], "rotation_deg": rot, "scale": scale, "matrix": view.tolist()}
        if effects.sag is not None:
            camera["motion"]["sag_deg"] = list(effects.sag)
    params = {
        "seed": int(seed), "floor": floor.to_dict(), "scene": scene.to_dict(), "effects": effects.to_dict(),
        "occupied_fraction": scene.occupied_fraction, "near_px": scene.near_px,
        "camera": camera,
        "image_size": [floor.width, floor.height], "lighting_draws": draws,
        "cell_states": {"occupied": OCCUPIED, "free": FREE, "ambiguous": AMBIGUOUS},
    }
    return GroundTruth(cells=cells.reshape(rows, cols), overlap=np.asarray(overlap, float).reshape(rows, cols),
                       centres_px=centres.reshape(rows, cols, 2), obstacles=obstacles,
                       obstacles_floor=[p.copy() for p in polys], kinds=list(kinds), textures=textures, params=params)
