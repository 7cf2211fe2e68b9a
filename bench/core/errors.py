"""The one error path of dpcbench: bad input raises `UserError`; everything else is a bug.

`UserError` is the only exception class for input that was checked and refused: a missing or
corrupt file, an unknown name, a parameter of the wrong type or out of range, an output path that
cannot or may not be written, a damaged results store. `dpcbench` prints its message as one line
(``dpcbench COMMAND: error: MESSAGE``) and exits 2. Any other exception is a bug in dpcbench and
propagates with its traceback, so that it can be reported and fixed; code must therefore never turn
a broad ``except ValueError`` / ``except Exception`` around computation into a `UserError`, only
the refusals of its own checks.

`UserError` subclasses `ValueError` and is defined in `metrics.errors`, the lowest layer, so that
the numpy-level API of ``methods/``, ``holes/`` and ``metrics/`` (scikit-learn convention: bad
parameters or data raise ValueError) raises it at its checks without importing ``bench``; this
module re-exports it for the harness.

Messages say it in the user's terms: which parameter or file, which value, what is allowed, and
what to do.

Warnings (`warn`): a questionable input that still gives a defined result is accepted with one
line on stderr (``dpcbench COMMAND: warning: MESSAGE``); the warnings of a command are kept in
`RECORDED` so that its output record (JSON) can store them beside the numbers they qualify.
"""

from __future__ import annotations

import warnings

from dpcbench.metrics.errors import UserError

__all__ = ["RECORDED", "InputWarning", "UserError", "warn"]


class InputWarning(UserWarning):
    """An input accepted with a caveat the user must see (printed as one line by the CLI)."""


#: messages of the warnings the running `dpcbench` command has shown (the CLI fills it, one entry per
#: line it prints, and clears it per command), for the command's output record
RECORDED: list[str] = []


def warn(message: str) -> None:
    """Issue an `InputWarning` (under `dpcbench`: one line on stderr, and recorded in `RECORDED`)."""
    warnings.warn(message, InputWarning, stacklevel=2)
