"""The ``--input-frame`` / ``--output-frame`` option type shared by the commands."""

from __future__ import annotations

import argparse

from imuhal.core.conventions import Convention, UnknownConvention, get_convention


def frame_argument(text: str) -> Convention:
    """An argparse ``type``: the named convention, or a one-line usage error listing them."""
    try:
        return get_convention(text)
    except UnknownConvention as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
