"""`dpcbench check-method NAME [--param KEY=VALUE ...]`: the conformance checks of
`dpcbench.testing.check_method` on a method: a built-in, a plug-in (entry point of group
``dpcbench.methods``) or an import path ``package.module:Class``.

Prints one line per check passed (with its seconds) and exits 0 when all pass; at the first failure
prints ``FAILED check 'NAME': WHY`` and exits 1. An unknown name or a method that cannot be
imported here is a usage error (exit 2). It runs the method four times on a tiny synthetic sequence
(3 frames of ~2 000 points): seconds for most methods.
"""

from __future__ import annotations

import sys

from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    parser = subparsers.add_parser("check-method", help="run the conformance checks on a method (yours or a built-in)",
                                   description=__doc__.split("\n\n", 1)[1])
    parser.add_argument("name", help="method: a registered name (`dpcbench list`) or an import path pkg.mod:Class")
    parser.add_argument("--param", action="append", metavar="KEY=VALUE",
                        help="method parameter (repeatable), as for `dpcbench inpaint`")
    parser.add_argument("--check", action="append", metavar="CHECK", dest="checks",
                        help="run only this check (repeatable; the checks it needs run first, unreported)")
    parser.set_defaults(func=run)


def run(args) -> int:
    from dpcbench.bench.core.params import check_param_types, parse_params
    from dpcbench.holes.lazy import is_import_path
    from dpcbench.methods.registry import METHODS, method_class
    from dpcbench.testing import CHECKS, ConformanceError, check_method

    if args.name not in METHODS:
        raise UserError(f"unknown method {args.name!r}; known methods: {', '.join(sorted(METHODS))}, or an import "
                        "path package.module:Class (see `dpcbench list`)")
    try:
        cls = method_class(args.name)
    except ImportError as err:
        raise UserError(f"{args.name}: cannot be used here: {err}") from None
    params = parse_params(args.param)
    check_param_types(cls, params, f"check-method {args.name}")
    checks = tuple(args.checks or CHECKS)
    unknown = [c for c in checks if c not in CHECKS]
    if unknown:
        raise UserError(f"--check: unknown check(s) {', '.join(unknown)}; known: {', '.join(CHECKS)}")
    # a registered name (built-in or entry point) must be the class's `name`; an import path names none
    name = None if is_import_path(args.name) and args.name not in METHODS.plugins else args.name

    def progress(check: str, seconds: float) -> None:
        print(f"ok      {check:<24} {seconds:7.2f} s", flush=True)

    try:
        timings = check_method(cls, params, name=name, checks=checks, progress=progress)
    except ConformanceError as err:
        print(f"FAILED  check {err.check!r}: {err.detail}", flush=True)
        print(f"dpcbench check-method: {args.name} does not conform (check {err.check!r})", file=sys.stderr)
        return 1
    print(f"{args.name}: {len(timings)} check(s) passed in {sum(timings.values()):.1f} s")
    return 0
