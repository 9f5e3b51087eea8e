"""docs/recording.md's Python example runs as written: it records an emulated GPS board and
replays it to the same floats."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_the_python_example_of_the_recording_docs_runs_as_written(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    text = (ROOT / "docs/recording.md").read_text()
    body = text.split("## From Python\n", 1)[1]
    code = re.search(r"```python\n(.*?)```", body, flags=re.S)
    assert code is not None
    (tmp_path / "profiles").symlink_to(ROOT / "profiles")
    monkeypatch.chdir(tmp_path)  # the example writes flight.imurec where it runs
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code.group(1), "docs/recording.md", "exec"), {})
    assert re.fullmatch(r"\d{4,} events, \d{4,} transactions replayed\n", out.getvalue())
    assert (tmp_path / "flight.imurec").stat().st_size > 0
