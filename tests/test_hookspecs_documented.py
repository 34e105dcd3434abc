"""Every hookspec is documented in the plugin guide, with an executed example, and tested.

Documented: docs/plugin-guide.md has a ``### `name(params) -> ...` `` heading whose parameters are
the hookspec's, and a ```` ```python ```` block (run by tests/test_docs.py) that implements it.
Tested: a test module other than this one implements the hook (``def name(``) and so exercises it
through a plugin manager.
"""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest

from sbplan import hookspecs

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "plugin-guide.md"


def hookspec_names() -> list[str]:
    return sorted(name for name, obj in vars(hookspecs).items()
                  if callable(obj) and hasattr(obj, f"{hookspecs.PROJECT}_spec"))


def test_there_are_hookspecs():
    assert "sbplan_register_stages" in hookspec_names()


@pytest.mark.parametrize("name", hookspec_names())
def test_hookspec_is_documented_with_its_signature(name):
    text = GUIDE.read_text(encoding="utf-8")
    headings = re.findall(rf"^###\s+`{name}\(([^)]*)\)[^`]*`", text, re.M)
    assert headings, f"docs/plugin-guide.md has no '### `{name}(...)`' section"
    documented = [p.split(":")[0].strip() for p in headings[0].split(",") if p.strip()]
    actual = list(inspect.signature(getattr(hookspecs, name)).parameters)
    assert documented == actual, f"{name}: the guide says ({', '.join(documented)}), the hookspec has ({', '.join(actual)})"


@pytest.mark.parametrize("name", hookspec_names())
def test_hookspec_has_an_executed_example(name):
    text = GUIDE.read_text(encoding="utf-8")
    python_blocks = re.findall(r"^```python\n(.*?)^```", text, re.S | re.M)
    assert any(re.search(rf"def {name}\(", b) for b in python_blocks), \
        f"docs/plugin-guide.md has no ```python example implementing {name}"


@pytest.mark.parametrize("name", hookspec_names())
def test_hookspec_is_tested(name):
    here = Path(__file__).resolve()
    users = [p.name for p in (ROOT / "tests").glob("test_*.py")
             if p.resolve() != here and re.search(rf"def {name}\(", p.read_text(encoding="utf-8"))]
    assert users, f"no test module implements {name}"
