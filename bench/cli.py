"""The `dpcbench` command line.

Each subcommand lives in its own module under `bench/commands/` and exposes
``register(subparsers)``, which adds its parser and sets ``func`` (a callable taking the parsed
arguments and returning an exit code). Modules are discovered, so adding a command never means
editing this file.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from bench import __version__
from bench.errors import UserError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="dpcbench",
        description="Benchmark and evaluation harness for inpainting holes in 3D dynamic point clouds.",
    )
    parser.add_argument("--version", action="version", version=f"dpcbench {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    import bench.commands as commands_pkg

    for info in sorted(pkgutil.iter_modules(commands_pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"bench.commands.{info.name}")
        module.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except UserError as err:
        print(f"dpcbench {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"dpcbench {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
