"""The scripts of docs/scripts (not a package) loaded as modules, for the tests that check
the figures and tables they write."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

SCRIPTS = Path(__file__).resolve().parents[2] / "docs" / "scripts"


def load_docs_script(name: str) -> ModuleType:
    """``docs/scripts/NAME.py`` as module ``NAME``, run afresh."""
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while being built
    spec.loader.exec_module(module)
    return module
