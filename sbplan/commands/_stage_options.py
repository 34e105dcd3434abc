"""Shared command-line options for choosing pipeline stages by name."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, cast

if TYPE_CHECKING:
    from ..contracts import StageChoices

STAGE_KINDS = ("binarizer", "extractor", "approximator", "matcher", "mapper", "footprint")


def add_stage_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("stages (names from 'sbplan plugins'; default: the calibrated ones)")
    for kind in STAGE_KINDS:
        group.add_argument(f"--{kind}", metavar="NAME", default=None, help=f"the {kind} stage")


def stage_choices(args: argparse.Namespace) -> StageChoices:
    """The stages named on the command line, validated against the registry (clear error if unknown)."""
    # imported when the command runs: the CLI starts without loading numpy and the plugins
    from .. import registry

    chosen = {k: getattr(args, k) for k in STAGE_KINDS if getattr(args, k, None)}
    for kind, name in chosen.items():
        registry.registry().info(kind, name)  # raises UnknownStageError listing the installed names
    return cast("StageChoices", chosen)  # keys from STAGE_KINDS, values names


def add_obstacle_model_argument(parser: argparse.ArgumentParser, *, what: str) -> None:
    """``--obstacle-model mar|parts|outline``: the same option, the same default, in every command."""
    from ..detection.obstacles import DEFAULT_OBSTACLE_MODEL, OBSTACLE_MODELS

    parser.add_argument("--obstacle-model", choices=OBSTACLE_MODELS, default=DEFAULT_OBSTACLE_MODEL,
                        help=f"what stands for each obstacle {what}: its minimum-area rectangle, rectangles "
                             f"of its parts, or its outline (default: %(default)s)")
