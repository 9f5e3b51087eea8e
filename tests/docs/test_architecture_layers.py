"""The layers picture in docs/architecture.md is the import-linter layers contract's."""

from __future__ import annotations

from pathlib import Path

from tests.support.docs_scripts import load_docs_script

layers_picture = load_docs_script("layers_picture")


def test_the_picture_in_the_document_is_the_one_made_from_importlinter() -> None:
    assert layers_picture.embedded() == layers_picture.picture(), (
        "docs/architecture.md's layers picture differs from .importlinter: run "
        ".venv/bin/python docs/scripts/layers_picture.py --write")


def test_every_layer_and_package_of_the_contract_is_in_the_picture_in_order() -> None:
    rows = layers_picture.layers()
    shown = [line.split()[:2] for line in layers_picture.picture().splitlines()[2:-1]]
    expected = [[str(n), p.removeprefix("imuhal.")]
                for n, row in enumerate(rows, start=1) for p in row]
    assert shown == expected and len(rows) >= 10


def test_a_package_moved_to_another_layer_changes_the_picture(tmp_path: Path) -> None:
    text = layers_picture.CONTRACTS.read_text()
    moved = tmp_path / ".importlinter"
    moved.write_text(text.replace("    imuhal.bus\n", "    imuhal.bus | imuhal.core\n", 1)
                     .replace("    imuhal.core\n", "", 1))
    assert layers_picture.picture(moved) != layers_picture.picture()
    assert "   10  core" in layers_picture.picture(moved)
