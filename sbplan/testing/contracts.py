"""The contract suites for pytest: subclass one as ``class TestX(MatcherContract)`` and set
``stage_class`` (with ``stage_options``) or ``stage_name``, or override the ``stage`` fixture."""

from __future__ import annotations

from typing import Any, ClassVar

import pytest

from .. import registry
from ..contracts import Stage
from .checks import (check_approximator_many, check_approximator_near_contour, check_approximator_rectangle,
                     check_binarizer_bands, check_binarizer_finds_ink, check_binarizer_locality, check_binarizer_output,
                     check_declaration, check_extractor_counts, check_extractor_empty, check_extractor_hole,
                     check_extractor_outer, check_extractor_rectangle, check_footprint_outlines, check_mapper,
                     check_matcher_descriptors, check_matcher_discriminates, check_matcher_distances,
                     check_matcher_invariance, check_planner_rejects_bad_start, check_planner_route,
                     check_registered)


class StageContract:
    """Base of the contract suites. Subclass a kind's suite as ``class TestX(<Kind>Contract)``.

    Set ``stage_class`` (and ``stage_options``), or ``stage_name`` to test the stage the registry
    holds under that name (what users get through entry points), or override the ``stage`` fixture.
    """

    kind: ClassVar[str] = ""
    stage_class: ClassVar[type[Stage] | None] = None
    stage_options: ClassVar[dict[str, Any]] = {}
    stage_name: ClassVar[str | None] = None

    @pytest.fixture
    def stage(self) -> Stage:
        if self.stage_name is not None:
            stage = registry.registry().create(self.kind, self.stage_name, **self.stage_options)
        elif self.stage_class is not None:
            stage = self.stage_class(**self.stage_options)
        else:
            raise pytest.UsageError(f"{type(self).__name__}: set stage_class or stage_name, or override the stage fixture")
        assert stage.kind == self.kind, f"{type(self).__name__} tests {self.kind}s, got a {stage.kind}"
        return stage

    def test_declaration(self, stage):
        check_declaration(stage)

    def test_registered(self, stage):
        if self.stage_name is None:
            pytest.skip("stage_class given: registration is not part of this suite (set stage_name)")
        check_registered(stage)


class BinarizerContract(StageContract):
    kind = "binarizer"

    def test_output(self, stage):
        check_binarizer_output(stage)

    def test_finds_ink(self, stage):
        check_binarizer_finds_ink(stage)

    def test_bands(self, stage):
        check_binarizer_bands(stage)

    def test_locality(self, stage):
        check_binarizer_locality(stage)


class ExtractorContract(StageContract):
    kind = "extractor"

    def test_rectangle(self, stage):
        check_extractor_rectangle(stage)

    def test_hole(self, stage):
        check_extractor_hole(stage)

    def test_region_and_hole_counts(self, stage):
        check_extractor_counts(stage)

    def test_empty(self, stage):
        check_extractor_empty(stage)

    def test_outer(self, stage):
        check_extractor_outer(stage)


class ApproximatorContract(StageContract):
    kind = "approximator"

    def test_rectangle(self, stage):
        check_approximator_rectangle(stage)

    def test_near_contour(self, stage):
        check_approximator_near_contour(stage)

    def test_many(self, stage):
        check_approximator_many(stage)


class MatcherContract(StageContract):
    kind = "matcher"

    def test_descriptors(self, stage):
        check_matcher_descriptors(stage)

    def test_distances(self, stage):
        check_matcher_distances(stage)

    def test_invariance(self, stage):
        check_matcher_invariance(stage)

    def test_discriminates(self, stage):
        check_matcher_discriminates(stage)


class MapperContract(StageContract):
    kind = "mapper"

    def test_occupancy_image(self, stage):
        check_mapper(stage)


class FootprintContract(StageContract):
    kind = "footprint"

    def test_outlines(self, stage):
        check_footprint_outlines(stage)


class PlannerContract(StageContract):
    kind = "planner"

    def test_route(self, stage):
        check_planner_route(stage)

    def test_rejects_start_in_obstacle(self, stage):
        check_planner_rejects_bad_start(stage)
