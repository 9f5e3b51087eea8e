"""The Freescale high-g reference data are what the documented recipe produces
(docs/scripts/fsl_highg/README.md): the committed files carry the recorded digests, and the
two input files regenerate byte for byte from imuhal's ``rc-flight`` scenario. The reference
outputs themselves need the public C library, so they are rebuilt on demand
(docs/scripts/fsl_highg/build_and_check.sh), not here."""

from __future__ import annotations

import hashlib
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data" / "filters"
RECIPE = ROOT / "docs" / "scripts" / "fsl_highg"
SUMS = dict(line.split()[::-1] for line in (RECIPE / "SHA256SUMS").read_text().splitlines())


@pytest.mark.parametrize("name", sorted(SUMS))
def test_committed_file_has_the_recorded_digest(name: str) -> None:
    assert hashlib.sha256((DATA / name).read_bytes()).hexdigest() == SUMS[name], (
        f"{name} changed: rebuild it with docs/scripts/fsl_highg/build_and_check.sh")


def test_inputs_regenerate_byte_for_byte_from_the_scenario(tmp_path: Path) -> None:
    spec = importlib.util.spec_from_file_location("fsl_highg_make_inputs",
                                                  RECIPE / "make_inputs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.make(tmp_path)
    for name in ("fsl_highg_counts.csv", "fsl_highg_truth.csv"):
        assert (tmp_path / name).read_bytes() == (DATA / name).read_bytes(), (
            f"{name} no longer regenerates: the rc-flight scenario changed, so the reference "
            "outputs are stale (docs/scripts/fsl_highg/README.md)")
