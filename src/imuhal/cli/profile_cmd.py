"""``imuhal profile check FILE...``: validate board profiles."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from imuhal.plugins.manager import Registry
from imuhal.profile.loader import check_profile

EXIT_INVALID = 2


def add_parser(sub: Any) -> None:
    profile = sub.add_parser("profile", help="work with board profiles")
    psub = profile.add_subparsers(dest="profile_command", metavar="ACTION")
    check = psub.add_parser("check", help="validate profiles; exit 0 when all are valid")
    check.add_argument("files", nargs="+", metavar="FILE")
    check.set_defaults(func=cmd_profile_check)

    def usage(args: argparse.Namespace, registry: Registry) -> int:
        profile.print_usage(sys.stderr)
        return EXIT_INVALID

    profile.set_defaults(func=usage)


def cmd_profile_check(args: argparse.Namespace, registry: Registry) -> int:
    bad = 0
    for file in args.files:
        problems = check_profile(file, registry)
        if problems:
            bad += 1
            print(f"{file}: INVALID ({len(problems)} problem{'s' if len(problems) > 1 else ''})")
            for p in problems:
                print(f"  {p}")
        else:
            print(f"{file}: ok")
    return EXIT_INVALID if bad else 0
