"""The named adverse conditions a scene is seen under, and the effects they set."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from ..errors import SceneError


@dataclass(frozen=True)
class Effects:
    """Lighting and camera effects of one image.

    Lighting is applied to the floor's reflectance: ``level = reflectance * illumination * gain +
    offset``, then additive highlights; then the camera: geometry (tilt, distortion), Gaussian blur,
    signal-dependent sensor noise, 8-bit quantization and optionally JPEG.

    Attributes
    ----------
    gain, offset : float
        Global exposure: multiplier and added grey levels.
    gradient : float
        Illumination ramp across the image: from ``1 - gradient`` to ``1 + gradient`` along a
        direction drawn from the seed.
    shadows : float
        Darkening (fraction, 0..0.8) of the soft shadows obstacles cast on the floor beside them.
    highlights : int
        Number of bright elliptic blobs (lighting errors / glare; they make round contours).
    highlight_strength : float
        Peak added grey level of a highlight, at most 110 so that dark ink under a highlight stays
        clearly darker than the floor around it (symbols stay recognizable, cells stay honest).
    noise : float
        Sensor noise standard deviation in grey levels at mid-grey (shot-noise-like: grows with
        the signal).
    blur : float
        Gaussian blur sigma in pixels (optics, focus).
    jpeg : int
        JPEG quality 1..100, or 0 for no compression.
    tilt : (float, float) or None
        Camera tilt in degrees about (x, y) axes, overriding the floor's. Geometry is a property of
        the fixed camera: render the reference with the same condition.
    distortion : float or None
        Radial distortion k1 overriding the floor's (same remark).
    texture_contrast : float
        Multiplier of the obstacles' texture amplitude (the "textured" condition raises it).
    motion : (float, float, float, float) or None
        The camera's movement since calibration: ``(dx, dy, rotation_deg, scale)``, a similarity of
        the image about its centre (:func:`sbplan.synth.camera.motion_matrix`): the scene shows
        what the calibrated view shows at ``p`` at ``scale * R(rotation) (p - c) + c + (dx, dy)``;
        rotation counter-clockwise as displayed. Scenes only: the reference is the calibration's
        view and never moves.
    vibration : float
        Random camera movement since calibration, drawn from the seed: a shift of up to
        ``8 * vibration`` px, a rotation of up to ``0.5 * vibration`` degrees and a zoom of up to
        ``1 % * vibration`` either way (added to ``motion``).
    drift : float
        A slow drift along one path, ``(6, -3) px, 0.4 deg, +0.8 %`` times ``drift`` times a point
        of the path drawn from the seed (a sequence of seeds samples the drift at several times).
    wear : float
        Floor wear after calibration, 0..1: thin scratches of floor colour across symbols (1 to 3 px
        wide), dark dirt specks (1 to 3 px) and dark tyre marks on the floor between symbols.
        Cells stay free: wear is not an obstacle.
    sag : (float, float) or None
        The camera tilted since calibration by ``(about_x, about_y)`` degrees (it sagged on its
        mount): a perspective change of the view about the image centre, composed after ``motion``
        (:func:`sbplan.synth.camera.view_change`). Scenes only, like ``motion``.
    shade : (float, float, polygon) or None
        A shadow cast by something outside the obstacles (a person walking past a lamp):
        ``(darkness, blur_px, outline)`` darkens the floor inside ``outline`` (``(K, 2)`` floor
        pixels ``(x, y)``) by ``darkness`` (0..0.8), with edges blurred by a Gaussian of sigma
        ``blur_px``. Cells stay free: a shadow is not an obstacle.
    """

    gain: float = 1.0
    offset: float = 0.0
    gradient: float = 0.0
    shadows: float = 0.0
    highlights: int = 0
    highlight_strength: float = 80.0
    noise: float = 1.5
    blur: float = 0.7
    jpeg: int = 0
    tilt: Any = None
    distortion: Any = None
    texture_contrast: float = 1.0
    motion: Any = None
    vibration: float = 0.0
    drift: float = 0.0
    wear: float = 0.0
    sag: Any = None
    shade: Any = None

    def __post_init__(self) -> None:
        checks = {
            "gain": (0.05, 3.0), "offset": (-100.0, 100.0), "gradient": (0.0, 0.8), "shadows": (0.0, 0.8),
            "highlights": (0, 50), "highlight_strength": (0.0, 110.0), "noise": (0.0, 40.0),
            "blur": (0.0, 8.0), "jpeg": (0, 100), "texture_contrast": (0.0, 5.0),
            "vibration": (0.0, 4.0), "drift": (0.0, 4.0), "wear": (0.0, 1.0),
        }
        for name, (lo, hi) in checks.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo <= v <= hi):
                raise SceneError(f"effects.{name}: must be a number in [{lo}, {hi}], got {v!r}")
        # camera angles: the tilt the reference shares, the sag that came after it
        for name, limit in (("tilt", 15), ("sag", 5)):
            v = getattr(self, name)
            if v is None:
                continue
            try:
                a, b = (float(x) for x in v)
            except (TypeError, ValueError):
                raise SceneError(f"effects.{name}: expected (about_x, about_y) degrees, got {v!r}") from None
            if max(abs(a), abs(b)) > limit:
                raise SceneError(f"effects.{name}: at most {limit} degrees, got {v!r}")
            object.__setattr__(self, name, (a, b))
        if self.distortion is not None and not (-0.3 <= float(self.distortion) <= 0.3):
            raise SceneError(f"effects.distortion: must lie in [-0.3, 0.3], got {self.distortion!r}")
        if self.motion is not None:
            try:
                dx, dy, rot, scale = (float(x) for x in self.motion)
            except (TypeError, ValueError):
                raise SceneError(f"effects.motion: expected (dx, dy, rotation_deg, scale), got {self.motion!r}") from None
            if not (math.hypot(dx, dy) <= 200 and abs(rot) <= 10 and 0.8 <= scale <= 1.25):
                raise SceneError(f"effects.motion: at most 200 px, 10 degrees and a scale in [0.8, 1.25], "
                                 f"got {self.motion!r}")
            object.__setattr__(self, "motion", (dx, dy, rot, scale))
        if self.shade is not None:
            try:
                darkness, blur, outline = self.shade
                darkness, blur = float(darkness), float(blur)
                outline = tuple((float(x), float(y)) for x, y in outline)
            except (TypeError, ValueError):
                raise SceneError(f"effects.shade: expected (darkness, blur_px, outline), got {self.shade!r}") from None
            if not (0.0 <= darkness <= 0.8 and 0.0 <= blur <= 100.0 and len(outline) >= 3):
                raise SceneError(f"effects.shade: darkness in [0, 0.8], blur_px in [0, 100] and an outline of "
                                 f"at least 3 points, got {self.shade!r}")
            object.__setattr__(self, "shade", (darkness, blur, outline))

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        if d["tilt"] is not None:
            d["tilt"] = list(d["tilt"])
        # camera movement and wear came later: left out at their defaults, so that the ground
        # truth of scenes without them reads as it always did
        for key, default in (("motion", None), ("vibration", 0.0), ("drift", 0.0), ("wear", 0.0), ("sag", None),
                             ("shade", None)):
            if d[key] == default:
                del d[key]
            elif key in ("motion", "sag"):
                d[key] = list(d[key])
            elif key == "shade":
                d[key] = {"darkness": d[key][0], "blur_px": d[key][1], "outline": [list(p) for p in d[key][2]]}
        return d


#: Condition name -> (description, effects that differ from the base camera and lighting).
_TABLE: dict[str, tuple[str, dict[str, Any]]] = {
    "clean": ("base lighting and camera: slight blur (0.7 px), mild sensor noise (1.5 levels)", {}),
    "bright": ("global gain +40 % (the floor saturates)", {"gain": 1.4}),
    "dark": ("global gain -40 %", {"gain": 0.6}),
    "gradient": ("illumination ramp from 0.65 to 1.35 across the image", {"gradient": 0.35}),
    "shadows": ("soft shadows cast beside every obstacle, darkening the floor by 50 %", {"shadows": 0.5}),
    "highlights": ("three bright elliptic glare blobs (+90 levels) partly washing out symbols",
                   {"highlights": 3, "highlight_strength": 90.0}),
    "noise": ("strong sensor noise (sigma 8 levels)", {"noise": 8.0}),
    "blur": ("defocus blur, sigma 1.8 px", {"blur": 1.8}),
    "jpeg": ("JPEG compression at quality 30", {"jpeg": 30}),
    "tilt": ("camera tilted 3 deg about x and 2 deg about y (perspective); reference shares it",
             {"tilt": (3.0, 2.0)}),
    "distortion": ("barrel lens distortion k1 = 0.06; reference shares it", {"distortion": 0.06}),
    "low-light": ("gain 0.25 with stronger noise (sigma 4): a dim, grainy image",
                  {"gain": 0.25, "offset": 3.0, "noise": 4.0}),
    "textured": ("obstacles with 2.5x stronger textures (stripes, labels, mottling)", {"texture_contrast": 2.5}),
    "adverse": ("gradient, shadows, two highlights, noise 4 and JPEG 60 together",
                {"gradient": 0.25, "shadows": 0.4, "highlights": 2, "highlight_strength": 80.0, "noise": 4.0,
                 "jpeg": 60}),
    # The camera moved after calibration (the reference is rendered unmoved).
    "shift-1": ("camera shifted by (0.7, -0.7) px since calibration (sub-pixel registration)",
                {"motion": (0.7, -0.7, 0.0, 1.0)}),
    "shift-8": ("camera shifted by (6.4, 4.8) px, 8 px in all, since calibration", {"motion": (6.4, 4.8, 0.0, 1.0)}),
    "rotation": ("camera rotated by 0.5 deg since calibration", {"motion": (0.0, 0.0, 0.5, 1.0)}),
    "zoom-in": ("camera 1 % closer to the floor since calibration (image scaled by 1.01)",
                {"motion": (0.0, 0.0, 0.0, 1.01)}),
    "zoom-out": ("camera 1 % farther (image scaled by 0.99) and shifted by (-3, 2) px since calibration",
                 {"motion": (-3.0, 2.0, 0.0, 0.99)}),
    "vibration": ("random camera movement per scene: up to 8 px, 0.5 deg and 1 % zoom", {"vibration": 1.0}),
    "drift": ("slow drift: a point of a path to (6, -3) px, 0.4 deg, +0.8 % per scene", {"drift": 1.0}),
    "sag": ("camera tilted by 1.5 deg about x and 1.5 deg about y since calibration (it sagged on its mount: "
            "a perspective change no similarity follows), plus random vibration",
            {"sag": (1.5, 1.5), "vibration": 1.0}),
    # The floor wore after calibration.
    "worn": ("scratches across symbols, dirt specks and dark tyre marks between symbols", {"wear": 1.0}),
    "worn-moved": ("worn floor, shadows and a camera moved by (-5, 3) px and 0.3 deg",
                   {"wear": 1.0, "shadows": 0.4, "motion": (-5.0, 3.0, 0.3, 1.0)}),
}

#: The named condition suite: name -> one-line description.
CONDITIONS: dict[str, str] = {name: desc for name, (desc, _) in _TABLE.items()}


def condition_effects(name: str) -> Effects:
    """The :class:`Effects` of a named condition."""
    if name not in _TABLE:
        raise SceneError(f"condition: unknown condition {name!r}; known: {', '.join(CONDITIONS)}")
    return Effects(**_TABLE[name][1])
