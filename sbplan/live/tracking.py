"""Stable state from noisy frames: per-cell hysteresis, and obstacles that keep their ids.

Cells are ``(row, col)``, row 0 the top row of symbols, as in :class:`sbplan.Detection`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import cv2
import numpy as np

from ..detection.obstacles import Obstacle
from ..errors import InputError


@dataclass(frozen=True)
class Hysteresis:
    """How long a cell must be seen changed before its state changes.

    Give ``frames`` (consecutive frames that showed the change; frames that could not be decoded
    or registered neither count nor break the run) or ``seconds`` (of the source's time since the
    first frame that showed it), or both (the change must pass both).

    >>> Hysteresis.parse("5"), Hysteresis.parse("0.4s")
    (Hysteresis(frames=5, seconds=None), Hysteresis(frames=None, seconds=0.4))
    """

    frames: int | None = 3
    seconds: float | None = None

    def __post_init__(self) -> None:
        if self.frames is None and self.seconds is None:
            raise InputError("hysteresis: give frames or seconds")
        if self.frames is not None:
            if isinstance(self.frames, bool) or not isinstance(self.frames, (int, np.integer)) or self.frames < 1:
                raise InputError(f"hysteresis: frames must be an integer >= 1, got {self.frames!r}")
            object.__setattr__(self, "frames", int(self.frames))
        if self.seconds is not None:
            if isinstance(self.seconds, bool) or not isinstance(self.seconds, (int, float)) \
                    or not math.isfinite(self.seconds) or self.seconds < 0:
                raise InputError(f"hysteresis: seconds must be a number >= 0, got {self.seconds!r}")
            object.__setattr__(self, "seconds", float(self.seconds))

    @classmethod
    def parse(cls, text: str) -> "Hysteresis":
        """``"5"`` (frames), ``"0.4s"`` (seconds) or ``"5,0.4s"`` (both)."""
        frames = seconds = None
        for part in str(text).replace(" ", "").split(","):
            try:
                if part.endswith("s"):
                    seconds = float(part[:-1])
                else:
                    frames = int(part)
            except ValueError:
                raise InputError(f"--hysteresis: expected frames (5), seconds (0.4s) or both (5,0.4s), "
                                 f"got {text!r}") from None
        return cls(frames=frames, seconds=seconds)

    def to_json(self) -> dict:
        return {"frames": self.frames, "seconds": self.seconds}


class CellHysteresis:
    """The stable occupancy of a grid, updated frame by frame.

    Every cell starts free. A cell flips when every frame since the first that showed it in the
    other state still shows it so, for :class:`Hysteresis` frames or seconds.

    Parameters
    ----------
    shape : (rows, cols)
    hysteresis : Hysteresis
    """

    def __init__(self, shape: tuple[int, int], hysteresis: Hysteresis):
        self.hysteresis = hysteresis
        self.stable = np.zeros(shape, bool)
        self._count = np.zeros(shape, np.int64)
        self._since = np.full(shape, np.nan)
        self._pending = False  # some cell seen changed and not flipped yet

    def update(self, occupied: np.ndarray, time_ms: float) -> np.ndarray:
        """One frame's occupied cells (rows, cols) bool at ``time_ms``; returns the cells whose
        stable state flipped (rows, cols) bool."""
        differ = occupied != self.stable
        if not differ.any():
            # the usual frame: nothing pending restarts, nothing flips
            if self._pending:
                self._count[:] = 0
                self._since[:] = np.nan
                self._pending = False
            return differ
        self._pending = True
        self._count = np.where(differ, self._count + 1, 0)
        self._since = np.where(differ, np.where(np.isnan(self._since), time_ms, self._since), np.nan)
        h = self.hysteresis
        flip = differ.copy()
        if h.frames is not None:
            flip &= self._count >= h.frames
        if h.seconds is not None:
            with np.errstate(invalid="ignore"):
                flip &= (time_ms - self._since) >= h.seconds * 1000.0 - 1e-6
        if flip.any():
            self.stable = self.stable ^ flip
            self._count[flip] = 0
            self._since[flip] = np.nan
        return flip


@dataclass(frozen=True)
class Change:
    """One obstacle's change between two stable states: ``kind`` is ``"appeared"``, ``"moved"``
    (its cells changed) or ``"left"``; ``obstacle`` the new state (the last one for ``left``),
    ``previous`` the old one (None for ``appeared``)."""

    kind: str
    obstacle: Obstacle
    previous: Obstacle | None = None


class ObstacleTracker:
    """Gives the obstacles of successive stable states ids that last while an obstacle stays.

    An obstacle of the new state takes the id of the old one it shares the most cells with (each
    old id goes to one new obstacle: when one splits, the part sharing the most cells keeps it, and
    of two merging, the one sharing the most; ties go to the most alike); one that shares
    no cell takes the id of an old obstacle left over within ``reach_px`` of its centre (moved
    farther than its own size between two states, e.g. when frames were dropped); the rest are
    new. Ids count up from 1 and are never reused.
    """

    def __init__(self, *, reach_px: float):
        self.reach_px = float(reach_px)
        self.obstacles: list[Obstacle] = []
        self._next = 1

    def update(self, found: list[Obstacle]) -> tuple[list[Obstacle], list[Change]]:
        """The obstacles of a new stable state (any ids) -> (the same with lasting ids, changes)."""
        old = self.obstacles
        old_cells = [set(map(tuple, o.cells)) for o in old]
        new_cells = [set(map(tuple, o.cells)) for o in found]
        pairs = sorted(((len(nc & oc), -len(oc ^ nc), i, j) for i, nc in enumerate(new_cells)
                        for j, oc in enumerate(old_cells) if nc & oc), reverse=True)
        taken_new: dict[int, int] = {}
        taken_old: set[int] = set()
        for _, _, i, j in pairs:
            if i not in taken_new and j not in taken_old:
                taken_new[i] = j
                taken_old.add(j)
        # no shared cell: the nearest obstacle left over, within reach
        spare_old = [j for j in range(len(old)) if j not in taken_old]
        for i in [i for i in range(len(found)) if i not in taken_new]:
            if not spare_old:
                break
            c = np.asarray(found[i].centre_px)
            d = [float(np.hypot(*(c - np.asarray(old[j].centre_px)))) for j in spare_old]
            k = int(np.argmin(d))
            if d[k] <= self.reach_px:
                taken_new[i] = spare_old.pop(k)
                taken_old.add(taken_new[i])
        out, changes = [], []
        for i, ob in enumerate(found):
            if i in taken_new:
                prev = old[taken_new[i]]
                ob = replace(ob, id=prev.id)
                if new_cells[i] != old_cells[taken_new[i]]:
                    changes.append(Change("moved", ob, prev))
            else:
                ob = replace(ob, id=self._next)
                self._next += 1
                changes.append(Change("appeared", ob))
            out.append(ob)
        for j, prev in enumerate(old):
            if j not in taken_old:
                changes.append(Change("left", prev, prev))
        out.sort(key=lambda o: o.id)
        order = {"left": 0, "moved": 1, "appeared": 2}
        changes.sort(key=lambda c: (order[c.kind], c.obstacle.id))
        self.obstacles = out
        return out, changes


def reusable_obstacles(occupied: np.ndarray, obstacles: Sequence[Obstacle], *,
                       keep: Callable[[Obstacle], bool] | None = None) -> tuple[list[Obstacle], np.ndarray]:
    """Which obstacles of the last stable state still stand as they were, and which cells need
    outlining anew.

    The occupied cells fall into groups of touching cells (8-connected, as the footprint stage
    looks one cell around them). A group whose cells are exactly one old obstacle's cells keeps
    that obstacle: outlining it again on a new frame would only redo the same work. Every other
    group is outlined anew: new, grown, shrunk, merged or split ones, and those the footprint had
    parted into several obstacles (touching objects, or one object a bad frame cut in two: a
    second look settles which). Obstacles the footprint left without a cell cannot be placed in a
    group, so then everything is outlined anew.

    Parameters
    ----------
    occupied : ndarray of shape (rows, cols), bool
        The new stable occupied cells, ``[row, col]``.
    obstacles : sequence of Obstacle
        The last stable state's obstacles (their ``cells`` are ``(row, col)``).
    keep : callable, optional
        ``keep(obstacle)`` False forbids reusing an obstacle (e.g. one outlined before the camera
        moved); its group is outlined anew.

    Returns
    -------
    kept : list of Obstacle
        The obstacles to keep as they are.
    outline : ndarray of shape (rows, cols), bool
        The occupied cells of the other groups.
    """
    occupied = np.asarray(occupied, bool)
    if not occupied.any() or not obstacles or any(not o.cells for o in obstacles):
        return [], occupied.copy()
    rows, cols = occupied.shape
    owner = np.full((rows, cols), -1, np.int64)
    for k, ob in enumerate(obstacles):
        r, c = np.asarray(ob.cells, np.int64).reshape(-1, 2).T
        if (r < 0).any() or (r >= rows).any() or (c < 0).any() or (c >= cols).any():
            return [], occupied.copy()
        owner[r, c] = k
    n, labels = cv2.connectedComponents(occupied.astype(np.uint8), connectivity=8)
    kept: list[Obstacle] = []
    outline = occupied.copy()
    for label in range(1, n):
        group = labels == label
        olds = np.unique(owner[group])
        if len(olds) != 1 or olds[0] < 0:
            continue  # a cell no obstacle held (the group grew), or several obstacles
        if not np.array_equal(owner == olds[0], group):
            continue  # its obstacle held cells outside the group now (it shrank or split)
        if keep is not None and not keep(obstacles[olds[0]]):
            continue
        kept.append(obstacles[olds[0]])
        outline &= ~group
    return kept, outline
