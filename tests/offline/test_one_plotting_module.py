"""Every figure imuhal draws comes from imuhal.offline.plotting: commands, docs scripts and
benchmarks reuse it instead of carrying their own matplotlib code (issue 12, item 2)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PLOTTING = ROOT / "src/imuhal/offline/plotting.py"
IMPORTS_MATPLOTLIB = re.compile(r"^\s*(import matplotlib|from matplotlib[. ])", re.M)


def test_only_the_plotting_module_imports_matplotlib() -> None:
    sources = [p for folder in ("src", "plugins", "docs/scripts", "tests/benchmarks")
               for p in (ROOT / folder).rglob("*.py")]
    assert PLOTTING in sources
    offenders = [str(p.relative_to(ROOT)) for p in sources
                 if p != PLOTTING and IMPORTS_MATPLOTLIB.search(p.read_text(encoding="utf-8"))]
    assert offenders == [], "draw figures through imuhal.offline.plotting"
