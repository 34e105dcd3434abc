"""What the local binarizers share: ink is darker than a local brightness level by a relative
offset, computed on a reduced image for speed, with thin streaks opened away."""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import ClassVar

import cv2
import numpy as np

from sbplan.contracts import Binarizer, option
from sbplan.errors import InputError
from sbplan.imageio import as_gray, halve
from sbplan.morphology import open_square


@dataclass(kw_only=True, frozen=True)
class LocalThresholdBinarizer(Binarizer):
    """Pixels darker than ``(1 - offset)`` times a local level (subclasses say which level).

    A base class, not a stage of its own (it has no name).
    """

    #: the window as a multiple of the symbol size, and its least side, when fitted to symbols
    window_per_symbol: ClassVar[float] = 1.0
    min_window: ClassVar[int] = 9

    window: int = option(0, "side of the local window in pixels; 0 = from the symbol size, else 31")
    offset: float = option(0.2, "how much darker than the local level ink is, as a fraction of that level")
    min_contrast: int = option(8, "grey levels below the local level that ink must be at the least")
    downscale: int = option(2, "the local level is computed on an image this many times smaller (speed)")
    opening: int = option(-1, "side of the square ink must contain (morphological opening); 0 = off, "
                              "-1 = a 25th of the symbol size, at least 3")

    def __post_init__(self) -> None:
        if self.window < 0 or (self.window and self.window < 3):
            raise InputError(f"window: must be 0 or >= 3 pixels, got {self.window}")
        if not 0.0 <= self.offset < 1.0:
            raise InputError(f"offset: must be in [0, 1), got {self.offset}")
        if self.min_contrast < 0:
            raise InputError(f"min_contrast: must be >= 0, got {self.min_contrast}")
        if self.downscale < 1:
            raise InputError(f"downscale: must be >= 1, got {self.downscale}")
        if self.opening < -1:
            raise InputError(f"opening: must be -1 (automatic), 0 (off) or a side in pixels, got {self.opening}")

    def with_symbol_size(self, size_px: float) -> "LocalThresholdBinarizer":
        """This binarizer with its automatic options fitted to symbols ``size_px`` pixels across."""
        fitted = self
        if not self.window:
            fitted = replace(fitted, window=max(int(round(size_px * self.window_per_symbol)), self.min_window))
        if self.opening == -1:
            fitted = replace(fitted, opening=max(3, int(round(size_px / 25))))
        return fitted

    def local_level(self, small: np.ndarray, window: int) -> np.ndarray:
        """The brightness ink is compared with, on the reduced image, for a window of ``window``
        reduced pixels. Same shape and dtype as ``small``."""
        raise NotImplementedError

    def local_level_rows(self, small: np.ndarray, window: int, rows: list[tuple[int, int]]) -> list[np.ndarray]:
        """:meth:`local_level`'s rows ``[a, b)`` for each ``(a, b)`` of ``rows``, exactly as the
        whole would give them. The default computes the whole level; a subclass whose last step
        looks only a bounded number of rows away can do that step on the rows asked for."""
        level = self.local_level(small, window)
        return [level[a:b] for a, b in rows]

    def level_reach(self, window: int) -> int:
        """How many reduced pixels away :meth:`local_level` looks for a window of ``window``: the
        whole window by default (safe for any window filter); subclasses that know better say so."""
        return window

    def locality(self) -> tuple[int, int]:
        """The local level looks :meth:`level_reach` reduced pixels away, each reduced pixel is
        ``f`` image pixels wide (a crop must start on one's corner), and the opening adds its half
        side (erosion, then dilation)."""
        window, f = self._window_factor()
        opening = 3 if self.opening == -1 else self.opening
        return f * (self.level_reach(window) + 1) + 2 * (opening // 2), f

    def binarize(self, gray: np.ndarray) -> np.ndarray:
        gray, thr, f = self._threshold(gray)
        return self._open(_below(gray, thr, f)).view(bool)

    def binarize_bands(self, gray: np.ndarray, bands) -> np.ndarray:
        """:meth:`binarize` limited to the row bands: the local level is estimated on the whole
        (reduced) image as always, the comparison and the opening run on the bands only."""
        gray = as_gray(gray, name="gray")
        h, w = gray.shape
        if bands.shape != (h, w):
            raise InputError(f"bands: made for {bands.shape[1]}x{bands.shape[0]}, the image is {w}x{h}")
        small, window, f = self._reduced(gray)
        if f not in _REPEAT or h != f * small.shape[0] or w != f * small.shape[1] or (bands.starts % f).any():
            level = self.local_level(small, window)
            return self._open(bands.stack(_below(gray, self._from_level(level), f))).view(bool)
        # the level of the bands' rows only (each band's rows of the reduced image)
        levels = self.local_level_rows(small, window, [(a // f, -(-b // f)) for a, b in
                                                       zip(bands.starts.tolist(), bands.stops.tolist())])
        # the threshold of every level value, repeated f times in one wide integer: one LUT call
        # per band instead of _from_level's three operations, a cast and a multiply
        table = _wide_table(self, f)
        w = gray.shape[1]
        out = np.empty(bands.stacked_shape, np.uint8)
        out[bands.offsets + (bands.stops - bands.starts)] = 0  # separator rows
        # numpy's comparison writes 0/1 (as bool) where cv2.compare writes 0/255, at the same speed:
        # the mask comes out as the contract wants it, without a thresholding pass
        ink = out.view(bool)
        for a, b, o, rows in zip(bands.starts.tolist(), bands.stops.tolist(), bands.offsets.tolist(), levels):
            # the threshold of the band's rows only, its columns repeated f times
            wide = cv2.LUT(rows, table).view(np.uint8)
            if (b - a) % f == 0:
                # the band's f row phases side by side (each reduced row's f image rows as one
                # long row) against the threshold row repeated f times: one comparison per band
                np.less(gray[a:b].reshape(-1, f * w), cv2.repeat(wide, 1, f), out=ink[o:o + b - a].reshape(-1, f * w))
                continue
            for phase in range(f):
                src = gray[a + phase:b:f]
                np.less(src, wide[:len(src)], out=ink[o + phase:o + b - a:f])
        return self._open(out).view(bool)

    def _threshold(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        """The validated image, the threshold on the reduced image, and the reduction factor."""
        gray = as_gray(gray, name="gray")
        level, f = self._level(gray)
        return gray, self._from_level(level), f

    def _level(self, gray: np.ndarray) -> tuple[np.ndarray, int]:
        """The local level on the reduced image, and the reduction factor."""
        small, window, f = self._reduced(gray)
        return self.local_level(small, window), f

    def _reduced(self, gray: np.ndarray) -> tuple[np.ndarray, int, int]:
        """The reduced image, the window in its pixels, and the reduction factor."""
        window, f = self._window_factor()
        return _reduce(gray, f), window, f

    def _window_factor(self) -> tuple[int, int]:
        """The window in reduced pixels, and the reduction factor."""
        window = self.window or 31
        # The local level varies slowly: computing it on a reduced image and enlarging it again
        # costs a fraction of the full-size filter.
        f = max(1, min(self.downscale, window // 5))
        return max(3, int(round(window / f))), f

    def _from_level(self, level: np.ndarray) -> np.ndarray:
        # OpenCV takes a number as src2 (a scalar); its stubs accept arrays only
        below = cv2.subtract(level, self.min_contrast)  # type: ignore[call-overload]
        return np.minimum(cv2.convertScaleAbs(level, alpha=1.0 - self.offset), below)

    def _open(self, ink: np.ndarray) -> np.ndarray:
        opening = 3 if self.opening == -1 else self.opening
        if opening > 1:
            # Shadow rims and texture lines are thin dark streaks; where one touches a symbol it
            # welds onto the symbol's outline. An opening removes streaks thinner than the square.
            # (shift-free for an even side too: sbplan.morphology)
            ink = open_square(ink, opening)
        return ink


def _reduce(gray: np.ndarray, f: int) -> np.ndarray:
    """``gray`` made ``f`` times smaller by area averaging. A factor of 4 is done as two halvings:
    OpenCV's direct 4x area reduction is ten times slower than its 2x one."""
    h, w = gray.shape
    if f == 1:
        return gray
    if f == 4 and h % 4 == 0 and w % 4 == 0:
        return halve(halve(gray))
    if f == 2 and h % 2 == 0 and w % 2 == 0:
        return halve(gray)
    return cv2.resize(gray, (max(1, w // f), max(1, h // f)), interpolation=cv2.INTER_AREA)


#: f -> (integer type, multiplier) that repeats a uint8 f times within one wider integer
_REPEAT = {2: (np.uint16, 0x0101), 4: (np.uint32, 0x01010101)}


@functools.lru_cache(maxsize=32)
def _wide_table(binarizer: LocalThresholdBinarizer, f: int) -> np.ndarray:
    """The LUT from a level value to its threshold (``binarizer._from_level``, which works value by
    value, so applied to all 256 values it is exact) repeated f times in one integer of
    :data:`_REPEAT`'s type, as a type OpenCV's LUT takes (int32 for f = 4: the same bits)."""
    thr = binarizer._from_level(np.arange(256, dtype=np.uint8)[None, :]).ravel()
    wide_type, repeat = _REPEAT[f]
    table = thr.astype(wide_type) * wide_type(repeat)
    return table.view(np.int32) if wide_type is np.uint32 else table


def _below(gray: np.ndarray, thr: np.ndarray, f: int) -> np.ndarray:
    """``gray < thr`` with ``thr`` enlarged ``f`` times by nearest neighbour: a 0/1 uint8 image of
    gray's shape.

    Nearest neighbour, because the threshold changes by a grey level or two between neighbouring
    reduced pixels, so interpolating would buy nothing. For ``f`` of 2 or 4 the threshold is never
    enlarged as an image: its columns are repeated by
    one integer multiply (each byte ``f`` times) and each of the ``f`` row phases of ``gray`` is
    compared with that in place. That is several times cheaper than ``cv2.resize(...,
    INTER_NEAREST)`` on a camera frame (0.08 ms against 0.5 ms at 1280x960, one core). Other
    factors, and sizes that are not multiples, take the plain route.
    """
    h, w = gray.shape
    if f == 1:
        return (gray < thr).view(np.uint8)
    if f in _REPEAT and h == f * thr.shape[0] and w == f * thr.shape[1]:
        wide_type, repeat = _REPEAT[f]
        wide = (thr.astype(wide_type) * repeat).view(np.uint8)
        out = np.empty((h, w), np.uint8)
        for phase in range(f):
            cv2.compare(gray[phase::f], wide, cv2.CMP_LT, dst=out[phase::f])
        # compare gives 0/255; the contract is 0/1 viewed as bool
        return cv2.threshold(out, 0, 1, cv2.THRESH_BINARY, dst=out)[1]
    big = cv2.resize(thr, (w, h), interpolation=cv2.INTER_NEAREST)
    return (gray < big).view(np.uint8)
