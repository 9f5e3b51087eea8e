"""The README's embedding example runs as written and prints what the README says it does."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def _blocks(section: str) -> list[tuple[str, str]]:
    text = README.read_text()
    body = text.split(f"## {section}\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```(\w*)\n(.*?)```", body, flags=re.S)


def test_the_embedding_example_labels_each_stream_as_the_readme_shows() -> None:
    (_, code), (_, shown) = _blocks("Embedding")[:2]
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, str(README), "exec"), {})
    printed = out.getvalue().splitlines()
    # The numbers move whenever a chip model or filter improves; the labels and layout the
    # README promises must not.
    assert [_masked(line) for line in printed[-2:]] == \
        [_masked(line) for line in shown.strip().splitlines()]
    assert {line.split(":")[0].split()[-1] for line in printed} == {"vario", "baro-only"}


def _masked(line: str) -> str:
    return re.sub(r"[+-]?\d+\.\d+", "#", line)
