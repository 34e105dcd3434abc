"""Installing a plugin project for the subprocess tests: the docs' and the plugin kit's tests run
the example plugin installed into a temporary folder, never into this environment."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import setuptools


def install_plugin(project: str | os.PathLike, target: str | os.PathLike) -> str:
    """Install a plugin project into the folder ``target``, offline, for use on ``PYTHONPATH``.

    Runs ``pip install --no-deps --no-build-isolation --no-index --target`` when the installed
    setuptools can build a wheel without downloading anything (setuptools >= 70.1, or the
    ``wheel`` package); otherwise lays the project out exactly as pip would: its packages (from
    ``[tool.setuptools] packages``) and a ``<name>-<version>.dist-info`` with ``METADATA`` and the
    ``entry_points.txt`` of its ``[project.entry-points]``. Either way sbplan finds the plugin only
    through its entry point. The current environment is not touched.

    Parameters
    ----------
    project : path
        Folder with the plugin's ``pyproject.toml`` (setuptools backend).
    target : path
        Folder to install into (created if missing).

    Returns
    -------
    str
        ``"pip"`` or ``"layout"``: which way was used.
    """
    project, target = Path(project), Path(target)
    target.mkdir(parents=True, exist_ok=True)
    version = tuple(int(x) for x in setuptools.__version__.split(".")[:2])
    if version >= (70, 1) or importlib.util.find_spec("wheel") is not None:
        subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                        "--no-index", "--target", str(target), str(project)], check=True, capture_output=True)
        return "pip"
    meta = tomllib.loads((project / "pyproject.toml").read_text(encoding="utf-8"))
    proj = meta["project"]
    for package in meta["tool"]["setuptools"]["packages"]:
        rel = package.replace(".", "/")
        shutil.copytree(project / rel, target / rel, ignore=shutil.ignore_patterns("__pycache__"), dirs_exist_ok=True)
    dist = target / f"{proj['name'].replace('-', '_')}-{proj['version']}.dist-info"
    dist.mkdir(exist_ok=True)
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {proj['name']}\nVersion: {proj['version']}\n",
                                   encoding="utf-8")
    lines = []
    for group, entries in proj.get("entry-points", {}).items():
        lines.append(f"[{group}]")
        lines += [f"{k} = {v}" for k, v in entries.items()]
    (dist / "entry_points.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return "layout"
