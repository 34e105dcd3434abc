"""Contracts of the pluggable stages.

A stage is a class with a ``kind`` (which contract it fulfils), a ``name`` (its key in the
registry), a one-line ``description`` and typed options. Options are dataclass fields: decorate a
concrete stage with ``@dataclass(kw_only=True)`` and declare each option with :func:`option`::

    @dataclass(kw_only=True)
    class MyMatcher(DescriptorMatcher):
        name = "mine"
        description = "What it does, in one line."
        harmonics: int = option(20, "number of Fourier amplitudes kept")

Instances are cheap, immutable in spirit and safe to share between threads.

The detection pipeline runs, per image: binarizer -> extractor -> length filter -> approximator ->
matcher -> occupancy mapper -> footprint. Planners turn obstacles into routes.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Sequence, TypedDict

import numpy as np

from .contours import Contour
from .errors import InputError, SbplanError, StageError

if TYPE_CHECKING:  # (the contracts are the foundation: the pipeline and the planner import them)
    from .detection.grid import Grid
    from .planning.route import Problem, Route

if typing.TYPE_CHECKING:
    from .detection.bands import RowBands

#: The stage kinds, in pipeline order.
KINDS = ("binarizer", "extractor", "approximator", "matcher", "mapper", "footprint", "planner")


def option(default: Any, help: str, **kwargs: Any) -> Any:
    """Declare a stage option: a dataclass field with a default and a help text."""
    if isinstance(default, (list, dict, set)):
        return dataclasses.field(default_factory=lambda: type(default)(default), metadata={"help": help}, **kwargs)
    return dataclasses.field(default=default, metadata={"help": help}, **kwargs)


@dataclass(frozen=True)
class OptionInfo:
    """What a user needs to know to set an option."""

    name: str
    type: type
    default: Any
    help: str


def _parse_value(raw: str, typ: type, name: str) -> Any:
    try:
        if typ is bool:
            low = raw.strip().lower()
            if low in ("1", "true", "yes", "on"):
                return True
            if low in ("0", "false", "no", "off"):
                return False
            raise ValueError(raw)
        return typ(raw)
    except (TypeError, ValueError):
        raise InputError(f"option {name}: {raw!r} is not a valid {typ.__name__}") from None


class Stage(ABC):
    """Base of every stage contract."""

    kind: ClassVar[str] = ""
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    #: Other names the registry finds the stage under (a library's own name for it, such as
    #: OMPL's ``RRTstar`` for ``rrt-star``); listings show ``name`` only.
    aliases: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def options(cls) -> list[OptionInfo]:
        """The stage's options with their types, defaults and help texts."""
        if not dataclasses.is_dataclass(cls):
            return []
        hints = typing.get_type_hints(cls)
        out = []
        for f in dataclasses.fields(cls):
            default = f.default if f.default is not dataclasses.MISSING else (
                f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
            typ = hints.get(f.name, str)
            out.append(OptionInfo(f.name, typ if isinstance(typ, type) else str, default, f.metadata.get("help", "")))
        return out

    @classmethod
    def from_strings(cls, pairs: Sequence[str] | dict[str, str] = ()) -> "Stage":
        """Build an instance from ``key=value`` strings (as typed on the command line)."""
        items = pairs.items() if isinstance(pairs, dict) else (
            p.split("=", 1) if "=" in p else (p, None) for p in pairs)
        known = {o.name: o for o in cls.options()}
        kwargs = {}
        for key, raw in items:
            key = key.strip().replace("-", "_")
            if raw is None:
                raise InputError(f"option {key!r} for {cls.kind} {cls.name!r}: expected key=value")
            if key not in known:
                listing = ", ".join(known) or "none"
                raise InputError(f"{cls.kind} {cls.name!r} has no option {key!r}; options: {listing}")
            kwargs[key] = _parse_value(raw, known[key].type, key)
        return cls(**kwargs)

    def config(self) -> dict[str, Any]:
        """The option values of this instance, for result files and reproducibility."""
        if not dataclasses.is_dataclass(self):
            return {}
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


class Binarizer(Stage):
    """Turns a grayscale image into the binary image contours are extracted from."""

    kind = "binarizer"

    @abstractmethod
    def binarize(self, gray: np.ndarray) -> np.ndarray:
        """Return the foreground mask.

        Parameters
        ----------
        gray : ndarray of shape (H, W), uint8
            The image, row-major ``(row, col)``.

        Returns
        -------
        ndarray of shape (H, W), bool
            True where the printed symbols' ink (the dark foreground) is.
        """

    def binarize_bands(self, gray: np.ndarray, bands: RowBands) -> np.ndarray:
        """The foreground mask of the row bands only, stacked (:meth:`sbplan.detection.bands.RowBands.stack`).

        Detection calls this when the symbols fill only part of the frame's rows. The default
        binarizes the whole image and stacks the bands, which gives the same mask as
        :meth:`binarize` but saves nothing; a binarizer whose per-pixel work can be limited to the
        bands overrides it, still looking at the whole image for anything it estimates from
        context (a floor level, a global threshold).

        Parameters
        ----------
        gray : ndarray of shape (H, W), uint8
        bands : RowBands
            For an image of shape (H, W).

        Returns
        -------
        ndarray of shape ``bands.stacked_shape``, bool
            Separator rows are False.
        """
        return bands.stack(self.binarize(gray), fill=False)

    def locality(self) -> tuple[int, int] | None:
        """How far the mask at a pixel looks, for detection that re-examines part of a frame.

        ``(reach, step)`` promises that :meth:`binarize` (and :meth:`binarize_bands`) of a crop of
        an image give, at every pixel of the crop farther than ``reach`` pixels (rows and columns)
        from a side of the crop that is not the image's own side, what they give there on the whole
        image, for any crop whose corners lie on multiples of ``step`` pixels of an image whose
        sides are multiples of ``step``. None (the default) promises nothing: a global threshold,
        or not known. A live watch then detects every changed frame whole
        (:meth:`sbplan.detection.Detector.find_cells_local`).
        """
        return None


class ContourExtractor(Stage):
    """Finds every closed boundary (outer boundaries and holes) of a binary image."""

    kind = "extractor"

    @abstractmethod
    def extract(self, binary: np.ndarray) -> list[Contour]:
        """Return the boundaries of the 8-connected foreground regions and of their holes.

        Parameters
        ----------
        binary : ndarray of shape (H, W), bool
            Foreground mask; pixels outside the image count as background.

        Returns
        -------
        list of Contour
            Outer boundaries run counter-clockwise as displayed (``orientation=+1``), holes
            clockwise (``orientation=-1``).
        """

    def extract_outer(self, binary: np.ndarray) -> list[Contour]:
        """Only the outer boundaries (``is_hole`` False), in :meth:`extract`'s order.

        Detection matches outer boundaries only, so this is what its hot path calls. The default
        filters :meth:`extract`; an extractor that can skip holes more cheaply overrides it. The
        ``parent`` of the returned contours is not meaningful (it may be -1).
        """
        return [c for c in self.extract(binary) if not c.is_hole]


class ContourApproximator(Stage):
    """Approximates a pixel contour by a polygon."""

    kind = "approximator"

    @abstractmethod
    def approximate(self, contour: Contour) -> np.ndarray:
        """Return the polygon's vertices, shape (M, 2) float64 ``(x, y)``, M >= 3 when possible,
        in the contour's traversal order, not closed (first vertex not repeated)."""

    def approximate_many(self, contours: Sequence[Contour]) -> Sequence[np.ndarray]:
        """:meth:`approximate` of every contour, in order. Detection calls this once per frame;
        override it when a batch is cheaper than one call per contour."""
        return [self.approximate(c) for c in contours]


class DescriptorMatcher(Stage):
    """Describes closed outlines by fixed-size vectors and measures how different two are."""

    kind = "matcher"
    #: distances below this mean "same shape" when no calibration has derived a better one.
    default_threshold: ClassVar[float] = 0.5

    @abstractmethod
    def describe(self, points: np.ndarray) -> np.ndarray:
        """Descriptor of one closed outline.

        Parameters
        ----------
        points : array_like of shape (N, 2)
            Vertices or boundary pixels ``(x, y)`` in traversal order, N >= 3, not closed.

        Returns
        -------
        ndarray of shape (K,), float64
            Finite, and of the same K for every input of this instance.
        """

    def describe_many(self, outlines: Sequence[np.ndarray]) -> np.ndarray:
        """Descriptors of many outlines, shape (n, K). Override where a batch is faster."""
        if len(outlines) == 0:
            return np.zeros((0, len(self.describe(np.array([[0, 0], [1, 0], [0, 1]], float)))))
        return np.stack([self.describe(p) for p in outlines])

    def distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """Distance between two descriptors: >= 0, symmetric, 0 for identical descriptors."""
        return float(self.distance_matrix(np.asarray(a)[None, :], np.asarray(b)[None, :])[0, 0])

    @abstractmethod
    def distance_matrix(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """All pairwise distances between the rows of ``a`` (n, K) and ``b`` (m, K): shape (n, m)."""


class OccupancyMapper(Stage):
    """Turns the grid's occupied cells into the occupancy image (paper section 4.1)."""

    kind = "mapper"

    @abstractmethod
    def occupancy_image(self, grid: Grid, occupied: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        """Return the occupancy image.

        Parameters
        ----------
        grid : sbplan.detection.grid.Grid
            The calibrated grid (cell centres in image pixels, rows x cols).
        occupied : ndarray of shape (rows, cols), bool
            True for occupied cells, indexed ``(row, col)``.
        shape : (H, W)
            The image's shape.

        Returns
        -------
        ndarray of shape (H, W), uint8
            0 (black) in occupied cells' blocks, 255 elsewhere.
        """


class FootprintRefiner(Stage):
    """Draws each obstacle's outline: from the occupied cells alone, or refined from the pixels in
    and around them.

    The cells stay the decision of *where* obstacles are (the paper's occupancy); a footprint
    stage decides how far each one reaches. Detection calls :meth:`prepare` once per detector
    (per calibration) and :meth:`outlines` once per frame.
    """

    kind = "footprint"
    #: The footprint stage (by name) detection uses instead when :meth:`prepare` returns None:
    #: a stage that needs something old calibration files lack names its fallback here.
    fallback: ClassVar[str | None] = None

    def prepare(self, calibration: Any) -> Any:
        """The per-calibration work, done once per :class:`~sbplan.detection.Detector`: what
        :meth:`outlines` reads on every frame. The default prepares nothing (None).

        A stage that cannot work with ``calibration`` (a file written before what it needs was
        stored) returns None and sets :attr:`fallback`; detection then uses that stage instead.
        """
        return None

    @abstractmethod
    def outlines(self, gray: np.ndarray, occupied: np.ndarray, occupancy: np.ndarray, calibration: Any,
                 camera: Any, prepared: Any) -> list[np.ndarray]:
        """The obstacles' outlines of one frame.

        Parameters
        ----------
        gray : ndarray of shape (H, W), uint8
            The frame, as the camera sees it now (it may have moved since calibration).
        occupied : ndarray of shape (rows, cols), bool
            The occupied cells, ``[row, col]``.
        occupancy : ndarray of shape (H, W), uint8
            The mapper's occupancy image (0 occupied), in calibration pixels.
        calibration : sbplan.detection.calibration.Calibration
        camera : sbplan.detection.registration.CameraMotion
            Calibration pixels -> the frame's pixels (``camera.to_frame``).
        prepared : object
            What :meth:`prepare` returned for this calibration.

        Returns
        -------
        list of ndarray of shape (K, 2), float64
            Closed outlines ``(x, y)`` in calibration pixels (first vertex not repeated, K >= 3),
            simple polygons that do not overlap. Every occupied cell's hidden symbol should lie in
            one of them; detection adds the cell for any occupied cell no outline reaches.
        """


class Planner(Stage):
    """Plans a collision-free route among polygonal obstacles."""

    kind = "planner"
    #: What its routes are sure to be, in a few words for people (``sbplan plan`` and the
    #: terminal app show it). Only a planner that proves its routes shortest sets ``exact``.
    guarantee: ClassVar[str] = "collision-free; not proven shortest"
    exact: ClassVar[bool] = False

    @abstractmethod
    def solve(self, problem: Problem, *, time_limit: float = 1.0) -> Route:
        """Solve a ``sbplan.planning.Problem`` and return a ``sbplan.planning.Route``."""


CONTRACTS: dict[str, type[Stage]] = {
    "binarizer": Binarizer,
    "extractor": ContourExtractor,
    "approximator": ContourApproximator,
    "matcher": DescriptorMatcher,
    "mapper": OccupancyMapper,
    "footprint": FootprintRefiner,
    "planner": Planner,
}


# -- calling stages ---------------------------------------------------------------------------------

def stage_origin(stage: Any) -> str:
    """Where a stage comes from: the distribution that registered it, else its class's module."""
    try:
        from . import registry

        return registry.registry().info(stage.kind, stage.name).origin
    except Exception:  # a stage made outside the registry (tests, scripts): its module says it
        return type(stage).__module__


def stage_failure(stage: Any, what: str) -> StageError:
    """The error for ``stage`` having done ``what`` wrong (its kind, name and origin in the message)."""
    return StageError(getattr(stage, "kind", "stage"), getattr(stage, "name", type(stage).__name__),
                      stage_origin(stage), what)


def call_stage(stage: Any, method: str, *args: Any, returns: Any = None, **kwargs: Any) -> Any:
    """``stage.method(*args, **kwargs)``, with what goes wrong turned into a :class:`StageError`
    that names the stage's kind, name and origin and says what was wrong.

    Every place that calls a stage (detection, calibration, planning) calls it through this
    function, so that a plugin's exception or broken result is reported the same way everywhere.
    sbplan's own errors (:class:`SbplanError`: a planner's "no route", a stage's option check)
    pass unchanged.

    Parameters
    ----------
    returns : callable, optional
        Given the result, returns None when it keeps the contract, else a short description of
        what is wrong with it ("None, expected an array of shape (n, 1)"). One cheap check
        (vectorized): this is the hot path.
    """
    try:
        out = getattr(stage, method)(*args, **kwargs)
    except SbplanError:
        raise
    except Exception as exc:
        text = str(exc).splitlines()[0] if str(exc) else ""
        raise stage_failure(stage, f"failed in {method}(): {type(exc).__name__}"
                                   + (f": {text}" if text else "")) from exc
    if returns is not None:
        problem = returns(out)
        if problem:
            raise stage_failure(stage, f"broke its contract: {method}() returned {problem}")
    return out


def describe_value(v: Any) -> str:
    """A short description of a value, for contract errors: ``None``, ``str``, ``array (3, 2) float64``."""
    if v is None:
        return "None"
    if isinstance(v, np.ndarray):
        return f"an array of shape {v.shape} and dtype {v.dtype}"
    return f"a {type(v).__name__}"


def array_of(shape: tuple, *, finite: bool = False, kinds: str = "biuf") -> Any:
    """A ``returns`` check for :func:`call_stage`: an ndarray of ``shape`` (None: any length there)
    whose dtype kind is one of ``kinds``, finite everywhere when ``finite``."""
    want = " x ".join("n" if e is None else str(e) for e in shape)
    fixed = None not in shape

    def check(v: Any) -> str | None:
        if not isinstance(v, np.ndarray) or v.dtype.kind not in kinds or (
                v.shape != shape if fixed else
                (v.ndim != len(shape) or any(e is not None and e != g for e, g in zip(shape, v.shape)))):
            return f"{describe_value(v)}, expected an array of shape ({want})"
        # one reduction, no temporary: NaN and infinities propagate into the sum
        if finite and v.size and not math.isfinite(v.sum()):
            return "NaN or infinite values"
        return None

    return check


def descriptors_of(matcher: Any, outlines: Sequence[np.ndarray]) -> np.ndarray:
    """``matcher.describe_many(outlines)`` through :func:`call_stage`: shape (n, K), finite."""
    return call_stage(matcher, "describe_many", outlines, returns=array_of((len(outlines), None), finite=True))


def distances_between(matcher: Any, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``matcher.distance_matrix(a, b)`` through :func:`call_stage`: shape (len(a), len(b)), finite."""
    return call_stage(matcher, "distance_matrix", a, b, returns=array_of((len(a), len(b)), finite=True))


def as_descriptors(descriptors, *, name: str = "descriptors") -> np.ndarray:
    """Validate matcher descriptors and return them as a float64 ``(n, K)`` array.

    What every ``DescriptorMatcher.distance_matrix`` checks first; a single ``(K,)`` descriptor
    becomes one row.

    Raises
    ------
    InputError
        If they are not a 1-D or 2-D array of finite numbers.
    """
    try:
        arr = np.asarray(descriptors, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: not an array of numbers ({exc})") from None
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2:
        raise InputError(f"{name}: expected descriptors of shape (n, K), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise InputError(f"{name}: descriptors contain NaN or infinite values")
    return arr


class StageChoices(TypedDict, total=False):
    """The detection stages chosen for :func:`sbplan.calibrate`, :func:`sbplan.detect` and
    :class:`~sbplan.detection.Detector` (``**choices``): kind -> registered name or stage instance."""

    binarizer: str | Binarizer
    extractor: str | ContourExtractor
    approximator: str | ContourApproximator
    matcher: str | DescriptorMatcher
    mapper: str | OccupancyMapper
