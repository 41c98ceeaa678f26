"""``haptic-recog`` command line: one entry point, one sub-command per component.

Each sub-command lives next to the code it drives and exposes ``add_parser(subparsers)``;
this module only wires them together (imports are lazy so ``--help`` stays fast).
"""

from __future__ import annotations

import argparse
import importlib
import sys

# name -> module that defines add_parser(subparsers) and sets func on its parser
SUBCOMMANDS: dict[str, str] = {
    "dataset": "haptic_env.dataset",
    "analysis": "haptic_env.recognizers.analysis",
    "evaluate": "agents.evaluate",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="haptic-recog", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for module in SUBCOMMANDS.values():
        importlib.import_module(module).add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
