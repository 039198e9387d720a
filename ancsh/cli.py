"""The ``ancsh`` command line.

Each sub-command lives next to the code it drives, in a module exposing
``register(subparsers)``; that function adds a parser whose ``func`` default
receives the parsed arguments and returns an exit code. Heavy imports happen
inside ``func``, so ``ancsh --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from . import __version__

# Modules that contribute sub-commands, in help order.
COMMAND_MODULES = [
    "ancsh.demo",
    "ancsh.learned.cli",
    "ancsh.learned.app_cli",
    "ancsh.data.cli",
    "ancsh.benchcli",
    "ancsh.solvers.icp.cli",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ancsh",
        description="Category-level articulated object pose estimation from a single depth image (ANCSH).",
    )
    parser.add_argument("--version", action="version", version=f"ancsh {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, KeyError) as exc:
        print(f"ancsh {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
