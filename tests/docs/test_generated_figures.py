"""Every figure block of the docs is what its script prints today.

A generated block (docs/scripts/docblock.py) names the command that makes it; that command
prints exactly the block. The cheap commands run here in every suite run, the expensive ones
on demand (``pytest -m long tests/docs/test_generated_figures.py``); docs/scripts/README.md
says which is which, and this test keeps that list complete and true. A figure edited by
hand, or left behind by a change to the code, is a failing line of the comparison."""

from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import pytest
from tests.support.docs_scripts import load_docs_script

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / "docs" / "scripts"
README = SCRIPTS / "README.md"


docblock = load_docs_script("docblock")
"""docs/scripts/docblock.py, the scripts' own reading and writing of blocks."""
BLOCKS = [b for page in sorted((ROOT / "docs").glob("*.md")) for b in docblock.blocks(page)]
ROW = re.compile(r"^\| `([\w/]+\.py)` \| (`([\w-]+)` )?.*? \| ([^|]+?) \|$", re.M)
CHECKED = ("suite", "on demand")


@dataclass(frozen=True)
class Listed:
    """A row of docs/scripts/README.md's table: a script, the block it writes (if it
    writes one) and how the suite re-runs it (``suite``, ``on demand`` or why not)."""

    script: str
    block: str | None
    how: str


def listed() -> list[Listed]:
    text = README.read_text(encoding="utf-8")
    return [Listed(m.group(1), m.group(3), m.group(4)) for m in ROW.finditer(text)]


def how_checked(block: Any) -> str | None:
    """How docs/scripts/README.md says ``block`` is re-run (None: not listed)."""
    return next((row.how for row in listed()
                 if (row.script, row.block) == (block.script, block.name)), None)


@cache
def printed(command: tuple[str, ...]) -> str:
    """What ``command`` (a docs/scripts script and its arguments) prints, run from the
    repository's root as the docs say."""
    done = subprocess.run([sys.executable, *command], cwd=ROOT, capture_output=True,
                          text=True, timeout=3600, check=False)
    assert done.returncode == 0, f"{' '.join(command)} failed:\n{done.stderr[-2000:]}"
    return done.stdout


def blocks_checked(how: str) -> list[Any]:
    """The generated blocks whose script docs/scripts/README.md lists as ``how``."""
    return [b for b in BLOCKS if how_checked(b) == how]


def test_every_script_is_listed_with_how_its_figures_are_checked() -> None:
    on_disk = {p.name for p in SCRIPTS.glob("*.py")}
    assert {row.script for row in listed()} == on_disk, (
        "docs/scripts/README.md must list every script (and no other), with `suite`, "
        "`on demand` or why it is not re-run")


def test_every_block_is_listed_as_re_run() -> None:
    assert BLOCKS, "no generated block found in docs/"
    for block in BLOCKS:
        assert how_checked(block) in CHECKED, (
            f"{block.page.name}: the {block.name} block of {block.script} is not listed as "
            "re-run by `suite` or `on demand` in docs/scripts/README.md")


def test_every_listed_block_is_in_the_docs() -> None:
    in_docs = {(b.script, b.name) for b in BLOCKS}
    for row in listed():
        if row.block is not None:
            assert (row.script, row.block) in in_docs, f"no {row.block} block of {row.script}"
        assert (row.block is not None) == (row.how in CHECKED), (
            f"{row.script}: a block is re-run (`suite` or `on demand`), nothing else is")


def assert_printed_by_its_script(block: Any) -> None:
    assert docblock.differences(block.body, printed(tuple(block.command))) == [], (
        f"{block.page.name}: the {block.name} block is not what `{' '.join(block.command)}` "
        "prints: re-run it with --write (and re-read the prose after it)")


@pytest.mark.slow
@pytest.mark.parametrize("block", blocks_checked("suite"),
                         ids=lambda b: f"{b.page.name}:{b.name}")
def test_a_cheap_block_is_what_its_script_prints(block: Any) -> None:
    assert_printed_by_its_script(block)


@pytest.mark.long
@pytest.mark.parametrize("block", blocks_checked("on demand"),
                         ids=lambda b: f"{b.page.name}:{b.name}")
def test_an_expensive_block_is_what_its_script_prints(block: Any) -> None:
    assert_printed_by_its_script(block)


@pytest.mark.slow
def test_a_figure_edited_by_hand_is_a_difference() -> None:
    block = next(b for b in BLOCKS if b.name == "recovery-table")
    output = printed(tuple(block.command))
    assert docblock.differences(block.body, output) == []
    row = next(line for line in block.body.splitlines() if line.startswith("| madgwick | recover"))
    figure = re.search(r"\d+\.\d\d", row)
    assert figure is not None
    edited_value = f"{float(figure.group()) + 0.01:.2f}"
    edited = block.body.replace(row, row.replace(figure.group(), edited_value))
    assert docblock.differences(edited, output) == [
        f"-{row.replace(figure.group(), edited_value)}", f"+{row}"]


def test_writing_a_block_replaces_only_the_text_between_its_markers() -> None:
    page = "intro\n<!-- t:start -->\nold 1.00\n<!-- t:end -->\nprose 1.00\n"
    assert docblock.replace_block(page, "t", "new 2.00\n") == (
        "intro\n<!-- t:start -->\nnew 2.00\n<!-- t:end -->\nprose 1.00\n")
