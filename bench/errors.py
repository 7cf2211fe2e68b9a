"""User-facing errors: the CLI prints their message (no traceback) and exits non-zero."""


class UserError(Exception):
    """Bad input from the user: a missing file, a corrupt PLY, an unknown name, a bad parameter.

    The message must say what is wrong and what to do about it.
    """
