"""The core never imports Textual: the TUI is a layer on top, not a dependency of the library."""

from __future__ import annotations

import subprocess
import sys


def test_core_and_planner_api_do_not_import_textual():
    code = (
        "import sys, sbplan, sbplan.registry, sbplan.detection, sbplan.detection.exports\n"
        "from sbplan import plan, replan, calibrate, detect\n"
        "sbplan.registry.stages()\n"
        "bad = sorted(m for m in sys.modules if m == 'textual' or m.startswith('textual.'))\n"
        "print(bad)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
