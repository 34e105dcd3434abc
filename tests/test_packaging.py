"""Every package and data file of the source tree is part of the installed distribution.

A package missing from pyproject.toml works in an editable install and breaks the README's
`pip install .`, so the list is checked against the tree.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_is_listed():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    found = set()
    for name, folder in config["package-dir"].items():
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / folder)
            found.add(".".join([name, *rel.parts]))
    assert found == listed


def test_every_stylesheet_is_package_data():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    for tcss in (ROOT / "sbplan").rglob("*.tcss"):
        package = ".".join(tcss.parent.relative_to(ROOT).parts)
        assert "*.tcss" in config["package-data"].get(package, []), tcss


# -- a package that behaves like a well-kept one (issue 18, items 8 and 9) ------------------------
import ast  # noqa: E402
import importlib.metadata  # noqa: E402
import re  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import zipfile  # noqa: E402

import pytest  # noqa: E402
from packaging.requirements import Requirement  # noqa: E402
from packaging.utils import canonicalize_name  # noqa: E402

import sbplan  # noqa: E402

PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_the_version_is_written_once():
    project = PROJECT["project"]
    assert "version" not in project and "version" in project["dynamic"]
    assert PROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "sbplan.__version__"}
    out = subprocess.run([sys.executable, "-m", "sbplan", "--version"], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout == f"sbplan {sbplan.__version__}\n"
    copies = [p for p in (ROOT / "sbplan").rglob("*.py")
              if re.search(rf"['\"]{re.escape(sbplan.__version__)}['\"]", p.read_text(encoding="utf-8"))]
    assert copies == [ROOT / "sbplan" / "__init__.py"]


def test_license_changelog_and_py_typed():
    assert PROJECT["project"]["license"] == "BSD-3-Clause" and PROJECT["project"]["license-files"] == ["LICENSE"]
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("BSD 3-Clause License") and "Copyright (c) 2026 the sbplan developers" in text
    assert "Neither the name of the copyright holder nor the names of its" in text  # the third clause
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert "## [Unreleased]" in changelog and f"## [{sbplan.__version__}]" in changelog
    assert (ROOT / "sbplan" / "py.typed").is_file()
    data = PROJECT["tool"]["setuptools"]["package-data"]["sbplan"]
    assert "py.typed" in data and "schemas/*.json" in data


def _third_party_imports() -> dict[str, set[str]]:
    """Top-level modules imported by the library (sbplan/ and the built-in plugins) -> the files."""
    first_party = {"sbplan"} | {p.name for p in (ROOT / "plugins").glob("sbplan_*")}
    found: dict[str, set[str]] = {}
    for folder in [ROOT / "sbplan", *(ROOT / "plugins").glob("sbplan_*")]:
        for path in folder.rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                         else [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module
                         else [])
                for name in names:
                    top = name.split(".")[0]
                    if top not in sys.stdlib_module_names and top not in first_party and top != "__future__":
                        found.setdefault(top, set()).add(path.relative_to(ROOT).as_posix())
    return found


def test_every_imported_distribution_is_declared():
    """Each third-party module the library imports belongs to a distribution it declares: a core
    dependency, or an extra (`testing` for the plugin kit's pytest parts, `serve` for the
    service), not one that only arrives as somebody else's dependency."""
    names = lambda reqs: {canonicalize_name(Requirement(r).name) for r in reqs}  # noqa: E731
    declared = names(PROJECT["project"]["dependencies"])
    for extra, reqs in PROJECT["project"]["optional-dependencies"].items():
        if extra != "test":  # the test extra installs the suite's tools, not the library's needs
            declared |= names(reqs)
    owners = importlib.metadata.packages_distributions()
    missing = []
    for module, files in sorted(_third_party_imports().items()):
        dists = {canonicalize_name(d) for d in owners.get(module, [module])}
        if not dists & declared:
            missing.append((module, sorted(dists), sorted(files)[:3]))
    assert not missing, missing


def test_installed_versions_satisfy_the_declared_bounds():
    """The environment the suite runs in is inside every bound; CI's clean install checks the same."""
    project = PROJECT["project"]
    for text in project["dependencies"] + project["optional-dependencies"]["test"]:
        req = Requirement(text)
        installed = importlib.metadata.version(req.name)
        assert req.specifier.contains(installed, prereleases=True), (text, installed)
    bounded = {Requirement(r).name: Requirement(r).specifier for r in project["dependencies"]}
    for name in ("opencv-python-headless", "ompl"):
        ops = {s.operator for s in bounded[name]}
        assert ">=" in ops and "<" in ops and "==" not in ops, (name, bounded[name])


def test_the_wheel_ships_types_schemas_and_license(tmp_path):
    """Build the wheel offline from a copy of the sources (pip, the installed setuptools)."""
    import shutil

    src = tmp_path / "src"
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name if src.exists() else (src.mkdir() or src / name))
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info", "build")
    shutil.copytree(ROOT / "sbplan", src / "sbplan", ignore=ignore)
    for plugin in (ROOT / "plugins").glob("sbplan_*"):
        shutil.copytree(plugin, src / "plugins" / plugin.name, ignore=ignore)
    build_requirement = Requirement(PROJECT["build-system"]["requires"][0])
    if not build_requirement.specifier.contains(importlib.metadata.version("setuptools")):
        pytest.skip(f"the installed setuptools is outside the build requirement {build_requirement}")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "--no-index",
                        "-w", str(tmp_path / "dist"), str(src)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    wheel, = (tmp_path / "dist").glob("sbplan-*.whl")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        meta = z.read(f"sbplan-{sbplan.__version__}.dist-info/METADATA").decode()
    assert "sbplan/py.typed" in names
    assert {f"sbplan/schemas/{n}.schema.json"
            for n in ("detection", "calibration", "route", "geojson", "service-events")} <= names
    assert "sbplan/live/schemas/events.schema.json" in names  # sbplan watch's events
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert f"Version: {sbplan.__version__}" in meta and "License-Expression: BSD-3-Clause" in meta
    for dist in ("PyYAML", "rich"):
        assert re.search(rf"^Requires-Dist: {dist}\b", meta, re.M | re.I), dist
