"""The registry and the public lookup API: built-ins through entry points, clear errors, isolation."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from dataclasses import dataclass

import numpy as np
import pytest

from sbplan import registry as plugins
from sbplan.contracts import KINDS, DescriptorMatcher, option
from sbplan.errors import InputError, PluginError, UnknownStageError
from sbplan.hookspecs import hookimpl


@dataclass(kw_only=True, frozen=True)
class AreaMatcher(DescriptorMatcher):
    """A toy matcher registered inline by the tests."""

    name = "test-area"
    description = "absolute area, for registry tests"
    scale: float = option(1.0, "multiplies the area")

    def describe(self, points):
        p = np.asarray(points, float)
        x, y = p[:, 0], p[:, 1]
        return np.array([self.scale * 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))])

    def distance_matrix(self, a, b):
        return np.abs(np.asarray(a)[:, None, 0] - np.asarray(b)[None, :, 0])


def plugins_packages() -> set[str]:
    import importlib.metadata

    return {ep.value.split(":")[0] for ep in importlib.metadata.entry_points(group="sbplan") if ep.dist.name == "sbplan"}


def test_builtin_stages_come_through_entry_points():
    reg = plugins.build_registry()
    builtin = [s for s in reg.all() if s.cls.__module__.split(".")[0] in plugins_packages()]
    assert builtin and {s.origin for s in builtin} == {"sbplan"}, "built-in stages are registered by the sbplan distribution's entry points"
    assert {"local-mean", "otsu"} <= set(reg.names("binarizer"))
    assert {"blocks", "cells"} <= set(reg.names("mapper"))


def test_every_kind_has_a_lookup_pair():
    for kind in KINDS:
        create, names = getattr(plugins, kind), getattr(plugins, f"{kind}_names")
        assert names() == sorted(names())
        for name in names():
            stage = create(name)
            assert stage.kind == kind and stage.name == name


def test_unknown_name_lists_the_installed_ones():
    with pytest.raises(UnknownStageError) as info:
        plugins.mapper("no-such-mapper")
    message = str(info.value)
    assert "no-such-mapper" in message
    for name in plugins.mapper_names():
        assert name in message


def test_inline_registration_and_removal():
    pm = plugins.get_plugin_manager()

    class Plugin:
        @hookimpl
        def sbplan_register_stages(self, registry):
            registry.add(AreaMatcher)

    pm.register(Plugin(), name="inline-test")
    reg = plugins.build_registry(pm)
    assert "test-area" in reg.names("matcher")
    assert reg.info("matcher", "test-area").origin == "inline-test"
    m = reg.create("matcher", "test-area", scale=2.0)
    assert m.distance(m.describe([[0, 0], [2, 0], [0, 2]]), m.describe([[0, 0], [1, 0], [0, 1]])) == pytest.approx(3.0)
    pm.unregister(name="inline-test")
    assert "test-area" not in plugins.build_registry(pm).names("matcher")


def test_options_are_typed_and_parsed_from_strings():
    opts = {o.name: o for o in AreaMatcher.options()}
    assert opts["scale"].type is float and opts["scale"].default == 1.0 and opts["scale"].help
    assert AreaMatcher.from_strings(["scale=2.5"]).scale == 2.5
    with pytest.raises(InputError, match="no option 'speed'"):
        AreaMatcher.from_strings(["speed=1"])
    with pytest.raises(InputError, match="not a valid float"):
        AreaMatcher.from_strings(["scale=fast"])


def test_duplicate_and_non_stage_registration_are_refused():
    reg = plugins.StageRegistry()
    reg.add(AreaMatcher)

    @dataclass(kw_only=True, frozen=True)
    class Other(AreaMatcher):
        pass

    with pytest.raises(PluginError, match="registered twice"):
        reg.add(Other)
    with pytest.raises(PluginError, match="does not subclass"):
        reg.add(int)  # type: ignore[arg-type]


def test_a_broken_plugin_is_reported_by_name_and_others_still_load(tmp_path):
    """A real installed distribution (a dist-info on sys.path) whose entry point cannot import."""
    dist = tmp_path / "broken_sbplan_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-sbplan-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[sbplan]\nbroken = sbplan_module_that_does_not_exist\n")
    code = textwrap.dedent(f"""
        import logging, sys, warnings
        sys.path.insert(0, {str(tmp_path)!r})
        from sbplan import registry as plugins
        records = []
        handler = logging.Handler()
        handler.emit = records.append
        logging.getLogger("sbplan").addHandler(handler)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            reg = plugins.build_registry()
        print([(f.plugin, f.origin) for f in reg.failures])
        print(len(reg.names("mapper")) >= 2)
        print(any("broken" in r.getMessage() for r in records), len(caught))
        try:
            reg.create("mapper", "nope")
        except Exception as exc:
            print(exc)
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    out = run.stdout.split("\n")
    assert out[0] == "[('broken', 'broken-sbplan-plugin')]"
    # logged (for -v and for applications that set up logging), never a raw RuntimeWarning
    assert out[1] == "True" and out[2] == "True 0"
    assert run.stderr == ""
    # who asks for a stage that is not there hears about the plugin that failed
    assert "unknown mapper 'nope'" in out[3] and "broken (ModuleNotFoundError" in out[3]


def test_a_broken_plugin_prints_nothing_on_commands_that_do_not_need_it(tmp_path):
    dist = tmp_path / "broken_sbplan_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-sbplan-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[sbplan]\nbroken = sbplan_module_that_does_not_exist\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    run = subprocess.run([sys.executable, "-m", "sbplan", "symbols", "list"], capture_output=True, text=True, env=env)
    assert run.returncode == 0 and run.stderr == ""
    listed = subprocess.run([sys.executable, "-m", "sbplan", "plugins"], capture_output=True, text=True, env=env)
    assert listed.returncode == 8 and "plugin 'broken'" in listed.stdout and "Warning" not in listed.stderr


def test_sbplan_plugins_command_lists_kind_name_origin_description(capsys):
    from sbplan.cli import main

    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].split() == ["KIND", "NAME", "ORIGIN", "DESCRIPTION"]
    assert any(line.split()[:3] == ["mapper", "blocks", "sbplan"] for line in out.splitlines())
