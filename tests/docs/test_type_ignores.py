"""Every ``# type: ignore`` in src/ and plugins/ names the error codes it silences and says
why after them (``# type: ignore[code]  # why``): a bare or unexplained one hides a mistake
the type checker (mypy, configured in pyproject.toml) would have found."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
IGNORE = re.compile(r"#\s*type:\s*ignore(?P<rest>.*)$")
EXPLAINED = re.compile(r"^\[[a-z-]+(, [a-z-]+)*\]  # \S")


def unexplained_ignores(text: str) -> list[int]:
    """Line numbers (1-based) of ``# type: ignore`` comments without codes or a reason."""
    return [n for n, line in enumerate(text.splitlines(), 1)
            if (m := IGNORE.search(line)) and not EXPLAINED.match(m.group("rest"))]


def test_a_bare_or_unexplained_ignore_is_found() -> None:
    text = ("a = 1  # type: ignore\n"
            "b = 2  # type: ignore[misc]\n"
            "c = 3  # type: ignore[misc]  # the value is checked above\n")
    assert unexplained_ignores(text) == [1, 2]


def test_every_type_ignore_names_its_codes_and_its_reason() -> None:
    found = [f"{path.relative_to(ROOT)}:{n}"
             for folder in ("src", "plugins") for path in sorted((ROOT / folder).rglob("*.py"))
             for n in unexplained_ignores(path.read_text(encoding="utf-8"))]
    assert not found, "add [code]  # why to: " + ", ".join(found)
