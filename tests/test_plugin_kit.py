"""The plugin author's kit: sbplan.testing's checks hold for the built-in stages, catch broken
stages, and the example out-of-tree plugin works once installed, through its entry point only."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from sbplan import registry as plugins
from sbplan.contours import Contour
from sbplan.contracts import (Binarizer, ContourApproximator, ContourExtractor, DescriptorMatcher, FootprintRefiner,
                              OccupancyMapper, Planner)
from sbplan.errors import UnknownStageError
from sbplan.testing import (CHECKS, ApproximatorContract, BinarizerContract, ExtractorContract, FootprintContract,
                            MapperContract,
                            MatcherContract, PlannerContract, calibrated_pipeline, check_stage, register_stage,
                            registered, sample_outlines, tiny_floor)  # noqa: F401  (fixtures are used by name)

from _plugin_install import install_plugin

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = ROOT / "plugins" / "sbplan-elliptic-fourier"


# -- the contract suites on the built-in stages --------------------------------------------------
# The sampling planners other than rrt-connect optimize for their whole time limit; one of them is
# enough to show the suite works on OMPL stages.
SLOW_PLANNERS = {"bit-star", "fmt-star", "informed-rrt-star", "prm-star", "rrt-star"}


def builtin(kind: str) -> list[str]:
    return [s.name for s in plugins.stages() if s.kind == kind and s.origin == "sbplan" and s.name not in SLOW_PLANNERS]


@pytest.mark.parametrize("kind", list(CHECKS))
def test_every_builtin_stage_meets_its_contract(kind):
    names = builtin(kind)
    assert names, f"no built-in {kind}"
    for name in names:
        check_stage(plugins.registry().create(kind, name))


class TestFourierByName(MatcherContract):
    stage_name = "fourier"


class TestOpenCVExtractorByName(ExtractorContract):
    stage_name = "opencv"


class TestDouglasPeuckerByName(ApproximatorContract):
    stage_name = "douglas-peucker"
    stage_options = {"epsilon": 1.0}


class TestLocalMeanByName(BinarizerContract):
    stage_name = "local-mean"


class TestCellsByName(MapperContract):
    stage_name = "cells"


class TestAuxCornerByName(PlannerContract):
    stage_name = "aux-corner"


class TestPixelsFootprintByName(FootprintContract):
    stage_name = "pixels"


# -- the checks fail on broken stages --------------------------------------------------------------

@dataclass(kw_only=True, frozen=True)
class LopsidedMatcher(DescriptorMatcher):
    name = "test-lopsided"
    description = "a broken matcher: its distance is not symmetric"

    def describe(self, points):
        p = np.asarray(points, float)
        return np.array([np.ptp(p[:, 0]) / max(np.ptp(p[:, 1]), 1e-9)])

    def distance_matrix(self, a, b):
        return np.maximum(np.asarray(a)[:, None, 0] - np.asarray(b)[None, :, 0], 0.0)


@dataclass(kw_only=True, frozen=True)
class AspectMatcher(LopsidedMatcher):
    name = "test-aspect"
    description = "a matcher that is not rotation invariant: bounding-box aspect ratio"

    def distance_matrix(self, a, b):
        return np.abs(np.asarray(a)[:, None, 0] - np.asarray(b)[None, :, 0])


@dataclass(kw_only=True, frozen=True)
class OpenContourExtractor(ContourExtractor):
    name = "test-open"
    description = "a broken extractor: returns the region's pixels in row order, not a boundary"

    def extract(self, binary):
        ys, xs = np.nonzero(binary)
        return [Contour(np.c_[xs, ys].astype(np.int64))] if len(xs) else []


@dataclass(kw_only=True, frozen=True)
class UInt8Binarizer(Binarizer):
    name = "test-uint8"
    description = "a broken binarizer: returns 0/255 instead of bool"

    def binarize(self, gray):
        return np.where(np.asarray(gray) < 128, 255, 0).astype(np.uint8)


@dataclass(kw_only=True, frozen=True)
class StraightLinePlanner(Planner):
    name = "test-straight"
    description = "a broken planner: the straight line, through any obstacle"

    def solve(self, problem, *, time_limit=1.0):
        from sbplan.planning import Route

        return Route(np.stack([problem.start, problem.goal]), planner=self.name)


@dataclass(kw_only=True, frozen=True)
class ReversedApproximator(ContourApproximator):
    name = "test-reversed"
    description = "a broken approximator: the contour's points in the opposite traversal sense"

    def approximate(self, contour):
        return np.asarray(contour.points, float)[::-1].copy()


@dataclass(kw_only=True, frozen=True)
class InvertedMapper(OccupancyMapper):
    name = "test-inverted"
    description = "a broken mapper: occupied cells white, everything else black"

    def occupancy_image(self, grid, occupied, shape):
        from sbplan_mappers.cells import CellsMapper

        return 255 - CellsMapper().occupancy_image(grid, occupied, shape)


@dataclass(kw_only=True, frozen=True)
class OneCellFootprint(FootprintRefiner):
    name = "test-one-cell"
    description = "a broken footprint: the first occupied cell's centre as a dot, whatever else is occupied"

    def outlines(self, gray, occupied, occupancy, calibration, camera, prepared):
        rows, cols = np.nonzero(occupied)
        if not len(rows):
            return []
        x, y = calibration.grid.centres_px[rows[0], cols[0]]
        return [np.array([[x, y], [x + 1, y], [x, y + 1]])] * 2


@pytest.mark.parametrize("stage, broken_check", [
    (OneCellFootprint(), "check_footprint_outlines"),
    (ReversedApproximator(), "check_approximator_rectangle"),
    (InvertedMapper(), "check_mapper"),
    (LopsidedMatcher(), "check_matcher_distances"),
    (AspectMatcher(), "check_matcher_invariance"),
    (OpenContourExtractor(), "check_extractor_rectangle"),
    (UInt8Binarizer(), "check_binarizer_output"),
    (StraightLinePlanner(), "check_planner_route"),
])
def test_the_checks_catch_broken_stages(stage, broken_check):
    import sbplan.testing as kit

    with pytest.raises(AssertionError, match=repr(stage.name)):
        getattr(kit, broken_check)(stage)
    with pytest.raises(AssertionError):
        check_stage(stage)


def test_declaration_check_wants_help_texts():
    from sbplan.contracts import option
    from sbplan.testing import check_declaration

    @dataclass(kw_only=True, frozen=True)
    class NoHelp(AspectMatcher):
        name = "test-nohelp"
        description = "an option without help"
        k: int = option(3, "")

    with pytest.raises(AssertionError, match="help"):
        check_declaration(NoHelp())


# -- fixtures ---------------------------------------------------------------------------------------

def test_register_stage_fixture_is_scoped_to_the_test(register_stage):
    register_stage(AspectMatcher)
    assert plugins.matcher("test-aspect").name == "test-aspect"
    assert plugins.registry().info("matcher", "test-aspect").origin == "test"


def test_registered_stage_is_gone_afterwards():
    with registered(AspectMatcher):
        assert "test-aspect" in plugins.matcher_names()
    assert "test-aspect" not in plugins.matcher_names()
    with pytest.raises(UnknownStageError):
        plugins.matcher("test-aspect")


def test_registered_restores_a_replaced_stage():
    @dataclass(kw_only=True, frozen=True)
    class FakeFourier(AspectMatcher):
        name = "fourier"
        description = "stands in for fourier during one block"

    original = plugins.registry().get("matcher", "fourier")
    with registered(FakeFourier):
        assert plugins.registry().get("matcher", "fourier") is FakeFourier
    assert plugins.registry().get("matcher", "fourier") is original


def test_tiny_floor_and_calibrated_pipeline(tiny_floor, calibrated_pipeline):
    assert tiny_floor.reference.shape == tiny_floor.scene.shape == (240, 320)
    assert tiny_floor.occupied.any() and not tiny_floor.occupied.all()
    cal = calibrated_pipeline.calibration
    assert cal.grid.shape == (3, 4)
    detection = calibrated_pipeline.detect()
    assert calibrated_pipeline.cell_errors(detection) == 0


def test_inline_stage_runs_in_the_pipeline(calibrated_pipeline, register_stage):
    # A matcher registered inline is usable by name in detection, like an installed one.
    @dataclass(kw_only=True, frozen=True)
    class Hu(DescriptorMatcher):
        name = "test-hu"
        description = "OpenCV's Hu moments, registered inline"
        default_threshold = 0.3

        def describe(self, points):
            return plugins.matcher("hu-moments").describe(points)

        def distance_matrix(self, a, b):
            return plugins.matcher("hu-moments").distance_matrix(a, b)

    register_stage(Hu)
    detection = calibrated_pipeline.detect(matcher="test-hu")
    assert detection.stages["matcher"] == "test-hu"
    assert calibrated_pipeline.cell_errors(detection) == 0


# -- the example plugin, installed out of tree ------------------------------------------------------

@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A folder where the example plugin is installed, for the subprocesses' PYTHONPATH only."""
    target = tmp_path_factory.mktemp("site")
    install_plugin(PLUGIN, target)
    return target


def _run(args, site: Path, cwd: Path, **kw) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300, **kw)


def test_not_installed_in_this_environment():
    # The test environment itself must stay clean: the plugin only exists in the subprocesses.
    assert "elliptic-fourier" not in plugins.matcher_names()


def test_installed_plugin_is_listed(installed, tmp_path):
    out = _run(["-m", "sbplan", "plugins", "--json"], installed, tmp_path)
    assert out.returncode == 0, out.stderr
    stages = {(s["kind"], s["name"]): s for s in json.loads(out.stdout)["stages"]}
    ef = stages[("matcher", "elliptic-fourier")]
    assert ef["origin"] == "sbplan-elliptic-fourier"
    assert [o["name"] for o in ef["options"]] == ["harmonics"]


def test_installed_plugin_detects_through_the_cli(installed, tmp_path):
    from sbplan.imageio import write_image
    from sbplan.testing import make_tiny_floor

    floor = make_tiny_floor()
    write_image(tmp_path / "reference.png", floor.reference)
    write_image(tmp_path / "scene.png", floor.scene)
    cal = _run(["-m", "sbplan", "calibrate", "reference.png", "-o", "cal.json", "--matcher", "elliptic-fourier"],
               installed, tmp_path)
    assert cal.returncode == 0, cal.stderr
    assert "(elliptic-fourier)" in cal.stdout
    det = _run(["-m", "sbplan", "detect", "scene.png", "-c", "cal.json", "--json"], installed, tmp_path)
    assert det.returncode == 0, det.stderr
    result = json.loads(det.stdout)
    assert result["stages"]["matcher"] == "elliptic-fourier"
    found = np.zeros(floor.occupied.shape, bool)
    for r, c in result["occupied_cells"]:
        found[r, c] = True
    assert ((found != floor.occupied) & ~floor.ambiguous).sum() == 0
    # and as an override of a calibration made with another matcher
    _run(["-m", "sbplan", "calibrate", "reference.png", "-o", "cal2.json"], installed, tmp_path)
    det2 = _run(["-m", "sbplan", "detect", "scene.png", "-c", "cal2.json", "--json", "--matcher", "elliptic-fourier"],
                installed, tmp_path)
    assert det2.returncode == 0, det2.stderr
    assert json.loads(det2.stdout)["occupied_cells"] == result["occupied_cells"]


def test_installed_plugin_in_the_match_benchmark(installed, tmp_path):
    out = _run(["-m", "sbplan", "bench", "match", "--make", "set", "--classes", "3", "--per-class", "3",
                "--size", "64", "--repeat", "1", "--matchers", "elliptic-fourier,fourier", "--json"], installed, tmp_path)
    if out.returncode == 2 and "invalid choice" in out.stderr:
        pytest.skip("sbplan bench match is not part of this installation yet")
    assert out.returncode == 0, out.stderr
    assert "elliptic-fourier" in out.stdout


TUI_SELECTOR = """
import asyncio, json
from textual.widgets import OptionList, Select
from sbplan.tui.app import SbplanApp

async def main():
    app = SbplanApp(None, auto=False)
    async with app.run_test(size=(160, 50)) as pilot:
        await pilot.pause()
        options = app.screen.query_one("#stage-matcher", Select).query_one(OptionList)
        print(json.dumps([str(options.get_option_at_index(i).prompt) for i in range(options.option_count)]))

asyncio.run(main())
"""


def test_installed_plugin_in_the_tui_stage_selector(installed, tmp_path):
    # The real app, headless: the calibration screen's matcher selector offers the plugin's stage.
    out = _run(["-c", TUI_SELECTOR], installed, tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    names = json.loads(out.stdout.strip().splitlines()[-1])
    assert "elliptic-fourier" in names and "fourier" in names


def test_unknown_matcher_without_the_plugin(calibrated_pipeline, tmp_path):
    from sbplan.imageio import write_image

    calibrated_pipeline.calibration.save(tmp_path / "cal.json")
    write_image(tmp_path / "scene.png", calibrated_pipeline.floor.scene)
    out = _run(["-m", "sbplan", "detect", "scene.png", "-c", "cal.json", "--matcher", "elliptic-fourier"],
               tmp_path / "empty-site", tmp_path)
    assert out.returncode != 0
    assert out.stderr.startswith("sbplan: error: unknown matcher 'elliptic-fourier'; installed:")


def test_plugin_own_tests_pass_when_installed(installed):
    out = _run(["-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"], installed, PLUGIN)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
    assert " passed" in out.stdout


def test_symbols_hook_adds_a_candidate_symbol():
    from sbplan.hookspecs import hookimpl
    from sbplan.synth import FloorSpec, render_reference

    class Plugin:
        @hookimpl
        def sbplan_register_symbols(self, registry):
            registry.add_symbol("test-tee", np.array([[0, 0], [1, 0], [1, 0.3], [0.65, 0.3], [0.65, 1],
                                                      [0.35, 1], [0.35, 0.3], [0, 0.3]]), description="a T")

    pm = plugins.get_plugin_manager()
    pm.register(Plugin(), name="symbols-test")
    reg = plugins.build_registry(pm)
    info = reg.symbols()["test-tee"]
    assert info.origin == "symbols-test" and info.description == "a T"
    # the registered outline is one the renderer can print on a floor
    ref = render_reference(FloorSpec(width=160, height=120, cols=2, rows=2, symbol=info.polygon), seed=0)
    assert (ref < 100).any()


def test_the_kit_imports_and_checks_without_pytest():
    # A plain install has no pytest (it is the `testing` extra): the checks must still work, and the
    # fixtures and contract suites must say what is missing instead of failing on import.
    code = (
        "import sys\n"
        "sys.modules['pytest'] = None  # any 'import pytest' now raises ModuleNotFoundError\n"
        "import sbplan.testing as kit\n"
        "from sbplan import registry\n"
        "kit.check_stage(registry.matcher('fourier'))\n"
        "print(sorted(kit.sample_outlines()), 'pytest' in sys.modules and sys.modules['pytest'] is not None)\n"
        "try:\n"
        "    from sbplan.testing import MatcherContract\n"
        "except ImportError as exc:\n"
        "    print('ImportError:', exc)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == "['blob', 'circle', 'ell', 'flag', 'square', 'thin-triangle'] False"
    assert lines[1].startswith("ImportError: sbplan.testing.MatcherContract needs pytest")
    assert "sbplan[testing]" in lines[1]
