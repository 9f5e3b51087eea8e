"""The README's embedding example runs as written and prints what the README says it does,
figures included."""

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
    assert {line.split(":")[0].split()[-1] for line in printed} == {"vario", "baro-only"}
    # The run is seeded: the README shows its last lines as they are. A chip model or filter
    # that moves them must update the README (paste the example's last two lines).
    assert printed[-2:] == shown.strip().splitlines()
