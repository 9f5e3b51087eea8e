"""The figures the docs quote come from the tables their scripts generate.

A generated table sits between ``<!-- NAME:start -->`` and ``<!-- NAME:end -->`` and names
the script in docs/scripts that writes it. The prose that follows it, up to the next heading,
reads its figures off the table: every decimal number there must be a cell of the table (to
the decimals quoted). Regenerating a table without re-reading its prose fails here, in
milliseconds; that the tables themselves are what their scripts print today is
tests/docs/test_generated_figures.py's check."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pytest
from tests.support.docs_scripts import load_docs_script

ROOT = Path(__file__).resolve().parents[2]
DOCS = sorted((ROOT / "docs").glob("*.md"))
GENERATED = load_docs_script("docblock").GENERATED
DECIMAL = re.compile(r"(?<![\w.])[-+]?\d+\.\d+(?![\w.])")
SCRIPT = re.compile(r"docs/scripts/([\w/]+\.py)")


@dataclass(frozen=True)
class GeneratedTable:
    """One generated table of a page and the prose after it (to the next heading)."""

    page: str
    name: str
    body: str
    prose: str


def generated_tables(page: str, text: str) -> list[GeneratedTable]:
    """The generated tables of a page, each with the prose after it: up to the next heading,
    run-in heading (a paragraph that opens in bold) or generated table."""
    out = []
    for m in GENERATED.finditer(text):
        after = text[m.end():]
        ends = [e.start() for e in (re.search(r"^#{1,6} ", after, re.M),
                                    re.search(r"\n\n\*\*", after),
                                    re.search(r"^<!-- [\w-]+:start -->", after, re.M)) if e]
        prose = after[:min(ends, default=len(after))]
        out.append(GeneratedTable(page, m.group(1), m.group(2), prose))
    return out


def unquoted_figures(table: GeneratedTable) -> list[str]:
    """The decimal numbers of the prose that no cell of the table gives (a cell matches a
    figure when it rounds to it at the figure's decimals; signs ignored, as prose quotes
    magnitudes)."""
    cells = [abs(float(c)) for c in DECIMAL.findall(table.body)]
    missing = []
    for figure in DECIMAL.findall(table.prose):
        decimals = len(figure.split(".")[1])
        value = abs(float(figure))
        if not any(round(c, decimals) == round(value, decimals) for c in cells):
            missing.append(figure)
    return missing


TABLES = [t for page in DOCS
          for t in generated_tables(page.name, page.read_text(encoding="utf-8"))]


def test_the_docs_have_generated_tables() -> None:
    assert {t.name for t in TABLES} >= {"as-user-table", "accuracy-table", "flight-table",
                                         "learning-table"}


def test_a_figure_the_table_does_not_give_is_found() -> None:
    table = GeneratedTable("x.md", "t", "| a | 0.40 | **3.06** |\n",
                           "tilt 0.40 and 3.1 deg, not 3.07 nor 0.41\n")
    assert unquoted_figures(table) == ["3.07", "0.41"]


def test_the_prose_after_a_table_ends_at_the_next_table_or_run_in_heading() -> None:
    text = ("<!-- a:start -->\n| 1.00 |\n<!-- a:end -->\nsays 1.00\n\n<!-- b:start -->\n"
            "| 2.00 |\n<!-- b:end -->\nsays 2.00\n\n**Next.** 3.00\n")
    tables = generated_tables("x.md", text)
    assert [t.prose.strip() for t in tables] == ["says 1.00", "says 2.00"]


@pytest.mark.parametrize("table", TABLES, ids=lambda t: f"{t.page}:{t.name}")
def test_each_generated_table_names_a_script_that_writes_it(table: GeneratedTable) -> None:
    scripts = SCRIPT.findall(table.body)
    assert scripts, f"{table.page}: the {table.name} table does not name its script"
    source = ROOT / "docs" / "scripts" / scripts[0]
    assert source.is_file(), f"{table.page}: {table.name}: no {source}"
    # its --write replaces what lies between the markers with what it generates
    assert table.name in source.read_text(encoding="utf-8"), (
        f"{source.name} does not name the {table.name} block it writes")


@pytest.mark.parametrize("table", TABLES, ids=lambda t: f"{t.page}:{t.name}")
def test_the_prose_after_a_table_quotes_only_its_figures(table: GeneratedTable) -> None:
    assert unquoted_figures(table) == [], (
        f"{table.page}: the prose after the {table.name} table quotes figures the table no "
        "longer gives: re-read them off the regenerated table")
