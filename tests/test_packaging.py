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
