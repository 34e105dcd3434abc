"""sbplan: obstacle detection using a structured background, and routes around the obstacles.

The top-level names are imported lazily so that ``import sbplan`` stays cheap.
"""

from __future__ import annotations

import importlib
import logging
from typing import Any

from .errors import (  # noqa: F401  (re-exported)
    CalibrationError,
    ContourError,
    DetectionError,
    ImageError,
    InputError,
    MapFormatError,
    PlanningError,
    PluginError,
    SbplanError,
    UnknownStageError,
)

#: The one place the version is written: pyproject.toml reads it (setuptools' dynamic version),
#: ``sbplan --version`` prints it.
__version__ = "0.1.0"

# The library logs and never prints (sbplan.logs); without a handler of the program's own, nothing shows.
logging.getLogger("sbplan").addHandler(logging.NullHandler())

#: public name -> module that defines it
_LAZY: dict[str, str] = {
    "registry": "sbplan.registry",
    "plugins": "sbplan.plugins",  # the old name of sbplan.registry, kept for the docs' examples
    "calibrate": "sbplan.detection",
    "Calibration": "sbplan.detection",
    "detect": "sbplan.detection",
    "Detection": "sbplan.detection",
    "plan": "sbplan.planning",
    "replan": "sbplan.planning",
    "Route": "sbplan.planning",
}


def __getattr__(name: str) -> Any:
    module_name = _LAZY.get(name)
    if module_name is None:
        raise AttributeError(f"module 'sbplan' has no attribute {name!r}")
    module = importlib.import_module(module_name)
    value = module if module_name.endswith("." + name) else getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(list(globals()) + list(_LAZY))
