"""Progress bars (tqdm) that stay silent when asked or when output is not a terminal-like stream."""

from __future__ import annotations

import os

from tqdm.auto import tqdm


def progress_bar(iterable=None, *, desc: str = "", total: int | None = None, unit: str = "it",
                 quiet: bool | None = None, initial: int = 0):
    """A tqdm bar on stderr; ``quiet`` (or DPCBENCH_QUIET=1) disables it. ``initial``: items already done
    before the bar starts (cached runs): counted in the position, not in the rate or the ETA."""
    if quiet is None:
        quiet = os.environ.get("DPCBENCH_QUIET", "") not in ("", "0")
    return tqdm(iterable, desc=desc, total=total, unit=unit, disable=quiet, leave=False, dynamic_ncols=True,
                initial=initial)
