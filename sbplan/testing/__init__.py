"""The plugin author's test kit: pytest fixtures and a contract test suite for every stage kind.

Use it from a test module, no conftest needed::

    from sbplan.testing import MatcherContract, calibrated_pipeline, register_stage, tiny_floor  # noqa: F401

    class TestMyMatcher(MatcherContract):
        stage_class = MyMatcher          # or: stage_name = "mine" (looked up through the registry)

    def test_in_the_pipeline(calibrated_pipeline, register_stage):
        register_stage(MyMatcher)
        detection = calibrated_pipeline.detect(matcher="mine")
        assert calibrated_pipeline.cell_errors(detection) == 0

Importing a fixture into a test module makes pytest use it there. The same fixtures are available
everywhere when this module is loaded as a pytest plugin (``pytest -p sbplan.testing``).

Fixtures
--------
tiny_floor : TinyFloor (session scope)
    A rendered 320 x 240 floor with 4 x 3 symbols: the empty reference, one scene with obstacles,
    and the scene's ground truth.
calibrated_pipeline : CalibratedPipeline (session scope)
    The calibration of ``tiny_floor`` with the default stages, and ``detect(**stages)``.
register_stage : callable (function scope)
    ``register_stage(cls)`` registers a stage class in the process-wide registry for one test.

Contract suites
---------------
:class:`BinarizerContract`, :class:`ExtractorContract`, :class:`ApproximatorContract`,
:class:`MatcherContract`, :class:`MapperContract`, :class:`FootprintContract`, :class:`PlannerContract`: subclass one in a
module whose name pytest collects (``class TestX(MatcherContract)``) and set ``stage_class`` (with
``stage_options``) or ``stage_name``, or override the ``stage`` fixture. Every ``check_*`` function
is also usable on its own; :func:`check_stage` runs the whole contract of a stage's kind and
raises ``AssertionError`` on the first violation.

Pictures and shapes used by the checks are made here with numpy and OpenCV; nothing is downloaded.

``import sbplan.testing`` needs no pytest: the checks (checks.py) and the floor and pipeline helpers
(pipeline.py) load with it, the fixtures (fixtures.py) and contract suites (contracts.py) on first
use, and those need pytest (``pip install "sbplan[testing]"``).
"""

from __future__ import annotations

import importlib
from typing import Any

from .checks import *  # noqa: F401,F403  (every check_* function, CHECKS, sample_outlines)
from .checks import CHECKS, check_stage, sample_outlines
from .pipeline import CalibratedPipeline, TinyFloor, make_calibrated_pipeline, make_tiny_floor, registered

#: name -> the submodule that defines it and imports pytest
_NEEDS_PYTEST: dict[str, str] = {
    **dict.fromkeys(["tiny_floor", "calibrated_pipeline", "register_stage"], "fixtures"),
    **dict.fromkeys(["StageContract", "BinarizerContract", "ExtractorContract", "ApproximatorContract",
                     "MatcherContract", "MapperContract", "FootprintContract", "PlannerContract"], "contracts"),
}

__all__ = [
    "ApproximatorContract", "BinarizerContract", "CHECKS", "CalibratedPipeline", "ExtractorContract", "FootprintContract",
    "MapperContract", "MatcherContract", "PlannerContract", "StageContract", "TinyFloor", "calibrated_pipeline",
    "check_stage", "make_calibrated_pipeline", "make_tiny_floor", "register_stage", "registered", "sample_outlines",
    "tiny_floor",
]


def __getattr__(name: str) -> Any:
    submodule = _NEEDS_PYTEST.get(name)
    if submodule is None:
        raise AttributeError(f"module 'sbplan.testing' has no attribute {name!r}")
    try:
        module = importlib.import_module(f"{__name__}.{submodule}")
    except ModuleNotFoundError as exc:
        if exc.name != "pytest":
            raise
        raise ImportError(f"sbplan.testing.{name} needs pytest, which is not installed: "
                          "pip install 'sbplan[testing]'", name=exc.name) from exc
    value = getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    # pytest finds the fixtures of ``pytest -p sbplan.testing`` through dir()
    return sorted(set(globals()) | set(_NEEDS_PYTEST))
