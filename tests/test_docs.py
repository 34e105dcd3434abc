"""The documentation's examples run, so they stay true.

Conventions in docs/*.md (the files listed in DOCS):

- ```` ```python ```` blocks are executed in order, in one namespace per document;
- ```` ```pycon ```` blocks are doctests (``>>>`` lines and their expected output) in that namespace;
- ```` ```console ```` blocks are shell sessions: each ``$ command`` runs, and its output (stdout
  and stderr together) must match the lines below it, with ``...`` standing for any text;
- other blocks (```` ```sh ````, ```` ```toml ````, ```` ```text ````) are not executed.

Each document runs in its own temporary folder holding links to the checkout's ``maps/`` and
``plugins/`` folders. Console commands run with the example plugin installed on ``PYTHONPATH``
(never in this environment), because the plugin guide shows it installed.
"""

from __future__ import annotations

import doctest
import os
import re
import subprocess
import sys
import types
from pathlib import Path

import pytest

from _plugin_install import install_plugin

ROOT = Path(__file__).resolve().parents[1]
DOCS = ["getting-started.md", "operator-guide.md", "plugin-guide.md", "api.md", "live.md"]
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.S | re.M)
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def blocks(text: str) -> list[tuple[str, str, int]]:
    """(language, body, line number) of every fenced block."""
    return [(m.group(1), m.group(2), text.count("\n", 0, m.start()) + 1) for m in FENCE.finditer(text)]


def console_steps(body: str) -> list[tuple[str, str]]:
    """``$ command`` lines with the output expected after each."""
    steps: list[tuple[str, list[str]]] = []
    for line in body.splitlines():
        if line.startswith("$ "):
            steps.append((line[2:], []))
        elif steps:
            steps[-1][1].append(line)
    return [(cmd, "\n".join(out).strip("\n") + "\n") for cmd, out in steps]


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    target = tmp_path_factory.mktemp("docs-site")
    install_plugin(ROOT / "plugins" / "sbplan-elliptic-fourier", target)
    return target


@pytest.mark.parametrize("name", DOCS)
def test_doc_examples(name, tmp_path, monkeypatch, site):
    path = ROOT / "docs" / name
    text = path.read_text(encoding="utf-8")
    for sub in ("maps", "plugins"):
        if (ROOT / sub).exists():
            (tmp_path / sub).symlink_to(ROOT / sub)
    monkeypatch.chdir(tmp_path)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in [str(site), os.environ.get("PYTHONPATH", "")] if p),
               COLUMNS="100")
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    # A real module, so that classes defined in the examples (dataclasses) can find their module.
    module = types.ModuleType(f"docs_{path.stem.replace('-', '_')}")
    monkeypatch.setitem(sys.modules, module.__name__, module)
    namespace = module.__dict__
    checker = doctest.OutputChecker()
    ran = 0
    for lang, body, line in blocks(text):
        where = f"{name}:{line}"
        if lang == "python":
            exec(compile(body, where, "exec"), namespace)
        elif lang == "pycon":
            test = doctest.DocTestParser().get_doctest(body, namespace, where, str(path), line)
            runner = doctest.DocTestRunner(optionflags=FLAGS)
            report: list[str] = []
            runner.run(test, out=report.append, clear_globs=False)
            namespace.update(test.globs)  # DocTest runs on a copy; later blocks see its names
            assert runner.failures == 0, f"{where}: doctest failed\n" + "".join(report)
        elif lang == "console":
            for cmd, expected in console_steps(body):
                out = subprocess.run(cmd, shell=True, cwd=tmp_path, env=env, capture_output=True, text=True,
                                     timeout=300)
                got = out.stdout + out.stderr
                assert checker.check_output(expected, got, FLAGS), \
                    f"{where}: `{cmd}` printed\n{got}\nexpected\n{expected}"
        else:
            continue
        ran += 1
    assert ran, f"{name}: no executable examples"


def test_plugin_guide_shows_the_real_pyproject():
    """The guide's pyproject excerpt is the example plugin's actual file, word for word."""
    text = (ROOT / "docs" / "plugin-guide.md").read_text(encoding="utf-8")
    real = (ROOT / "plugins" / "sbplan-elliptic-fourier" / "pyproject.toml").read_text(encoding="utf-8")
    excerpts = [body for lang, body, _ in blocks(text) if lang == "toml"]
    assert excerpts, "the plugin guide shows the example plugin's pyproject.toml"
    for body in excerpts:
        assert body.strip() in real


#: Pages other parts of the project write (their authors work in parallel): a link to one of them
#: may precede the page itself.
ANNOUNCED = {"scenes.md", "planning.md", "tui.md", "symbols.md"}


def test_docs_link_to_files_that_exist():
    for name in DOCS:
        text = (ROOT / "docs" / name).read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", text):
            if target in ANNOUNCED:
                continue
            assert (ROOT / "docs" / target).exists(), f"{name}: broken link {target}"


def test_console_step_parser():
    steps = console_steps("$ a\none\ntwo\n$ b\n")
    assert steps == [("a", "one\ntwo\n"), ("b", "\n")]
