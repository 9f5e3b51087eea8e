"""``imuhal profile check FILE...``: validate board profiles; ``imuhal profile schema``: their
JSON Schema for editors."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from imuhal.plugins.manager import Registry
from imuhal.profile.json_schema import driver_settings_schema, profile_schema
from imuhal.profile.loader import check_profile

EXIT_INVALID = 2


def add_parser(sub: Any) -> None:
    profile = sub.add_parser("profile",
                             help="work with board profiles: check them, print their JSON Schema")
    psub = profile.add_subparsers(dest="profile_command", metavar="ACTION")
    check = psub.add_parser("check", help="validate profiles; exit 0 when all are valid")
    check.add_argument("files", nargs="+", metavar="FILE")
    check.set_defaults(func=cmd_profile_check)
    schema = psub.add_parser(
        "schema", help="print the JSON Schema of profiles (with every installed plugin)",
        description="Print the JSON Schema of a board profile: buses, devices and estimators "
        "with the settings of every installed bus kind, driver and estimator. Save it and "
        "point your editor at it (docs/profiles.md, 'Editor support').")
    schema.add_argument("--driver", metavar="NAME",
                        help="print only the schema of this driver's settings")
    schema.set_defaults(func=cmd_profile_schema)

    def usage(args: argparse.Namespace, registry: Registry) -> int:
        profile.print_usage(sys.stderr)
        return EXIT_INVALID

    profile.set_defaults(func=usage)


def cmd_profile_schema(args: argparse.Namespace, registry: Registry) -> int:
    if args.driver:
        schema = driver_settings_schema(registry, args.driver)
    else:
        schema = profile_schema(registry)
    print(json.dumps(schema, indent=2))
    return 0


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
