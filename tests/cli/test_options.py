"""imuhal.cli.options: a command's flag-combination rules as data; the first broken one is
the user's one-line error, and a value argparse should have typed is an internal error."""

from __future__ import annotations

import argparse
from typing import ClassVar

import pytest
from pydantic import ValidationError

from imuhal.cli.options import CommandOptions, Needs
from imuhal.cli.run_options import RunOptions
from imuhal.core.errors import ImuhalError


class _Options(CommandOptions):
    RULES: ClassVar[tuple[Needs, ...]] = (
        Needs(lambda o: o.samples, lambda o: o.output is not None, "--samples needs --output"),
        Needs(lambda o: o.workers is not None, lambda o: o.workers >= 1,
              lambda o: f"--workers {o.workers}: give 1 or more"),
    )

    samples: bool = False
    output: str | None = None
    workers: int | None = None


def test_options_that_go_together_pass_and_keep_their_values() -> None:
    opts = _Options.from_args(argparse.Namespace(samples=True, output="a.csv", workers=2,
                                                 func=print))
    assert (opts.samples, opts.output, opts.workers) == (True, "a.csv", 2)


def test_the_first_broken_rule_is_the_error_quoting_the_value() -> None:
    with pytest.raises(ImuhalError, match=r"^--samples needs --output$"):
        _Options.from_args(argparse.Namespace(samples=True, output=None, workers=0))
    with pytest.raises(ImuhalError, match=r"^--workers 0: give 1 or more$"):
        _Options.from_args(argparse.Namespace(samples=False, output=None, workers=0))


def test_a_value_of_the_wrong_type_is_a_bug_not_a_user_mistake() -> None:
    with pytest.raises(ValidationError):
        _Options.from_args(argparse.Namespace(samples=False, workers="many"))


def test_a_run_without_profile_is_emulated_and_one_with_a_profile_is_not() -> None:
    assert RunOptions.from_args(argparse.Namespace(profile=None, seed=3)).emulated
    with pytest.raises(ImuhalError, match="real hardware has no seed"):
        RunOptions.from_args(argparse.Namespace(profile="board.yaml", seed=3))
