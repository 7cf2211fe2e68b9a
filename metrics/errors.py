"""The error class of the numpy API (``metrics/``, ``holes/``, ``methods/``): input refused by a check.

`UserError` subclasses `ValueError` (scikit-learn convention: bad parameters or data raise
ValueError), so callers of the numpy API catch what they always caught. It marks the refusals of
the package's own checks, which say what is wrong and what to do; any other exception is a bug.
It lives in ``metrics`` because ``metrics`` is the lowest layer (metrics < holes < methods <
bench) and every layer raises it; `bench.core.errors` re-exports it, and the ``dpcbench`` command prints
its message as one line and exits 2.
"""

from __future__ import annotations


class UserError(ValueError):
    """Bad input: a bad parameter, an empty or malformed cloud, an unknown name, a corrupt file.

    The message must say what is wrong and what to do about it.
    """

    def __init__(self, message: str):
        super().__init__(message)

    def __str__(self) -> str:  # a KeyError-like repr never reaches the user: the text, as written
        return str(self.args[0]) if self.args else ""
