"""The kit's pytest fixtures: ``tiny_floor``, ``calibrated_pipeline`` and ``register_stage``."""

from __future__ import annotations

import contextlib
from typing import Callable, Iterator

import pytest

from ..contracts import Stage
from .pipeline import CalibratedPipeline, TinyFloor, make_calibrated_pipeline, make_tiny_floor, registered


@pytest.fixture(scope="session")
def tiny_floor() -> TinyFloor:
    """A rendered 320 x 240 floor of 4 x 3 symbols with a scene of two obstacles and its truth."""
    return make_tiny_floor()


@pytest.fixture(scope="session")
def calibrated_pipeline(tiny_floor: TinyFloor) -> CalibratedPipeline:
    """The default pipeline calibrated on ``tiny_floor``; ``.detect(matcher=...)`` runs detection."""
    return make_calibrated_pipeline(tiny_floor)


@pytest.fixture
def register_stage() -> Iterator[Callable[..., type[Stage]]]:
    """``register_stage(cls, origin="test")``: make ``cls`` findable by name (``sbplan.registry``,
    ``calibrate``, ``detect``, ``plan``) until the end of the test."""
    with contextlib.ExitStack() as stack:
        def add(cls: type[Stage], *, origin: str = "test") -> type[Stage]:
            stack.enter_context(registered(cls, origin=origin))
            return cls

        yield add
