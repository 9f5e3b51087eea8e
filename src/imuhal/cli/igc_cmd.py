"""``imuhal igc verify FILE``: check the G record of an IGC log imuhal wrote."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from imuhal.core.errors import ImuhalError
from imuhal.plugins.manager import Registry


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "igc", help="IGC flight logs: verify the G record of a log `imuhal run --igc` wrote",
        description="IGC flight logs written by `imuhal run --igc` (docs/flight-instrument.md).")
    actions = p.add_subparsers(dest="igc_action", metavar="ACTION", required=True)
    verify = actions.add_parser(
        "verify", help="check that the file is intact (exit 0) or say why not (exit 2)",
        description="Check an imuhal IGC file: its last line must be the G record, the "
        "SHA-256 of every byte before it. Detects corruption and truncation, not tampering: "
        "the G record has no key. A file cut by a crash (FILE.partial) verifies up to its "
        "last record.")
    verify.add_argument("file", metavar="FILE.IGC")
    verify.set_defaults(func=cmd_verify)


def cmd_verify(args: argparse.Namespace, registry: Registry) -> int:
    from imuhal.sinks.flight.igc import IgcCheckError, verify_igc

    try:
        check = verify_igc(args.file)
    except IgcCheckError as exc:
        raise ImuhalError(str(exc)) from None
    span = f", fixes {check.first_fix}-{check.last_fix} UTC" if check.b_records else ""
    print(f"{args.file}: ok ({check.records} records, {check.b_records} B records{span}; "
          "G record intact - not a signature of an approved logger)", file=sys.stdout)
    return 0
