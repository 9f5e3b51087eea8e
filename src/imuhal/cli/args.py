"""Argument types and the parser class shared by every command: each mistake is one line
naming the option, the value given and what to give instead (exit 2)."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from typing import NoReturn

EXIT_USAGE = 2


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage mistake as one line (``imuhal run: error: ...; see
    imuhal run --help``) instead of the usage block followed by the message."""

    def error(self, message: str) -> NoReturn:
        print(f"{self.prog}: error: {message}; see `{self.prog} --help`", file=sys.stderr)
        sys.exit(EXIT_USAGE)


def _number(text: str, what: str, example: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number; give {what}, e.g. "
                                         f"{example}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number; give {what}, e.g. "
                                         f"{example}")
    return value


def positive_float(what: str, example: str,
                   maximum: float = math.inf) -> Callable[[str], float]:
    """A finite number > 0 and <= ``maximum`` (durations, rates, field strengths)."""
    def parse(text: str) -> float:
        value = _number(text, what, example)
        if value <= 0:
            raise argparse.ArgumentTypeError(f"{text!r} must be greater than 0; give {what}, "
                                             f"e.g. {example}")
        if value > maximum:
            raise argparse.ArgumentTypeError(f"{text!r} is more than {maximum:g}; give {what}, "
                                             f"e.g. {example}")
        return value
    parse.__name__ = what  # argparse names the type in its own messages
    return parse


def int_at_least(minimum: int, what: str, example: str) -> Callable[[str], int]:
    """A whole number >= ``minimum`` (sample counts, seeds)."""
    def parse(text: str) -> int:
        try:
            value = int(text, 0)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number; give {what}, "
                                             f"e.g. {example}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{text!r} must be at least {minimum}; give "
                                             f"{what}, e.g. {example}")
        return value
    parse.__name__ = what
    return parse


MAX_SECONDS = 1e9
"""Longest duration accepted (31 years): times are int64 nanoseconds."""

seconds = positive_float("a duration in seconds", "60", MAX_SECONDS)
MAX_RATE_HZ = 1e6
"""Highest sample rate accepted: beyond it, consecutive int-nanosecond times would collide."""

rate_hz = positive_float("a sample rate in Hz", "100", MAX_RATE_HZ)
seed = int_at_least(0, "a seed (0 or more)", "1")
