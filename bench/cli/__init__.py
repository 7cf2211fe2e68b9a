"""The `dpcbench` command line.

Each subcommand lives in its own module under `bench/cli/commands/` and exposes
``register(subparsers)``, which adds its parser and sets ``func`` (a callable taking the parsed
arguments and returning an exit code). Modules are discovered, so adding a command never means
editing this file.

Error path (see `bench.core.errors`): a `UserError` (bad input, refused by a check) and a bad command
line are printed as ONE line on stderr, ``dpcbench COMMAND: error: MESSAGE``, exit status 2; an
`OSError` while writing one of the command's declared outputs (disk full, permissions) likewise.
Anything else is a bug and propagates with its traceback. Warnings print as one line each,
``dpcbench COMMAND: warning: MESSAGE``.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
import warnings

from dpcbench.bench import __version__
from dpcbench.bench.core.errors import RECORDED, UserError


def one_line(text: object) -> str:
    """The message (``str(text)``: a string or an exception) on one line, newlines and runs of spaces folded."""
    return " ".join(str(text).split())


class OneLineParser(argparse.ArgumentParser):
    """argparse with its usage errors on one line (exit 2), like every other refusal."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see `{self.prog} --help`)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="dpcbench",
        description="Benchmark and evaluation harness for inpainting holes in 3D dynamic point clouds.",
    )
    parser.add_argument("--version", action="version", version=f"dpcbench {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    import dpcbench.bench.cli.commands as commands_pkg

    for info in sorted(pkgutil.iter_modules(commands_pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"dpcbench.bench.cli.commands.{info.name}")
        module.register(subparsers)
    return parser


def _show_warning(command: str):
    def show(message, category, filename, lineno, file=None, line=None):
        RECORDED.append(one_line(message))
        print(f"dpcbench {command}: warning: {one_line(message)}", file=sys.stderr)
    return show


def main(argv: list[str] | None = None) -> int:
    from dpcbench.bench.data import outputs

    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    RECORDED.clear()
    outputs.CLAIMED.clear()
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = _show_warning(args.command)
        try:
            return int(args.func(args) or 0)
        except UserError as err:
            print(f"dpcbench {args.command}: error: {one_line(err)}", file=sys.stderr)
            return 2
        except BrokenPipeError:  # the reader went away (`dpcbench list | head`): stop quietly, as Unix tools do
            import os

            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 141
        except OSError as err:
            target = outputs.claimed_target(err)
            if target is None:
                raise  # not one of the command's outputs: a bug, with its traceback
            print(f"dpcbench {args.command}: error: cannot write {target}: {one_line(err.strerror or err)}; "
                  "free space or choose another output path", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(f"dpcbench {args.command}: interrupted", file=sys.stderr)
            return 130
