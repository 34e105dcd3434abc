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


# -- stage kinds: sbplan_register_stages takes a class of every kind; each is documented and has a
#    contract suite in the plugin kit, like the hooks above
from sbplan.contracts import CONTRACTS, KINDS  # noqa: E402


@pytest.mark.parametrize("kind", KINDS)
def test_stage_kind_is_documented_in_the_guides_contract_table(kind):
    text = GUIDE.read_text(encoding="utf-8")
    section = text.split("## Stage contracts", 1)[1].split("\n## ", 1)[0]
    assert re.search(rf"^\| {kind} \|", section, re.M), f"docs/plugin-guide.md's contract table has no '{kind}' row"


@pytest.mark.parametrize("kind", KINDS)
def test_stage_kind_has_a_contract_suite_and_checks(kind):
    import sbplan.testing as kit

    assert kit.CHECKS.get(kind), f"sbplan.testing.CHECKS has no checks for {kind}"
    suites = [getattr(kit, n) for n in kit.__all__ if n.endswith("Contract") and n != "StageContract"]
    assert any(getattr(s, "kind", None) == kind for s in suites), f"sbplan.testing has no contract suite for {kind}"


@pytest.mark.parametrize("kind", KINDS)
def test_stage_kind_is_implemented_by_a_test_stage(kind):
    """A test module defines a stage of the kind (its contract's class as a base): the registry's
    kind comes from the class, and the kit's checks are run on it."""
    here = Path(__file__).resolve()
    name = CONTRACTS[kind].__name__
    users = [p.name for p in (ROOT / "tests").glob("test_*.py")
             if p.resolve() != here and re.search(rf"class \w+\({name}\)", p.read_text(encoding="utf-8"))]
    assert users, f"no test module defines a {name} subclass"
