"""Write tests/slow_tests.txt: the tests marked ``slow`` (deselect them with ``-m "not slow"`` for a
quick loop). Rule: a test is slow when its setup, call and teardown took at least ``--threshold``
seconds (default 2) in a full run of the suite; this script makes that run (``--durations=0``) or
reads the output of one (``--log FILE``). Usage, from the repository root:

    .venv/bin/python -m tests.slow_list                 # runs the suite (about 8 minutes on 2 cores)
    .venv/bin/python -m tests.slow_list --log run.txt   # from `pytest -q --durations=0 > run.txt`
"""

from __future__ import annotations

import argparse
import collections
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LIST = REPO / "tests" / "slow_tests.txt"
_DURATION = re.compile(r"^\s*([\d.]+)s (?:call|setup|teardown)\s+(\S+)")
HEADER = """\
# Tests marked `slow` by tests/conftest.py: those whose setup + call + teardown took at least {threshold:g} s in a
# full run (`.venv/bin/python -m tests.slow_list` regenerates this file; the rule is there). The quick loop
# skips them: `.venv/bin/python -m pytest -q -m "not slow"`. The README's test command runs them all.
"""


def durations(log: str) -> dict[str, float]:
    """node id -> seconds (setup + call + teardown) from pytest's ``--durations=0`` lines."""
    total: dict[str, float] = collections.defaultdict(float)
    for line in log.splitlines():
        match = _DURATION.match(line)
        if match:
            total[match.group(2)] += float(match.group(1))
    return dict(total)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--log", type=Path, help="output of `pytest -q --durations=0` (else the suite is run)")
    parser.add_argument("--threshold", type=float, default=2.0, help="seconds (default 2)")
    args = parser.parse_args(argv)
    if args.log:
        log = args.log.read_text()
    else:
        done = subprocess.run([sys.executable, "-m", "pytest", "-q", "--durations=0", "-p", "no:cacheprovider"],
                              cwd=REPO, capture_output=True, text=True)
        log = done.stdout
        if done.returncode not in (0, 1):
            print(done.stdout[-2000:] + done.stderr[-2000:], file=sys.stderr)
            return 2
    times = durations(log)
    if not times:
        print("no --durations lines found: pass the output of `pytest -q --durations=0`", file=sys.stderr)
        return 2
    slow = sorted(node for node, seconds in times.items() if seconds >= args.threshold)
    LIST.write_text(HEADER.format(threshold=args.threshold) + "".join(f"{node}\n" for node in slow))
    print(f"{len(slow)} of {len(times)} timed tests are slow ({sum(times[n] for n in slow):.0f} s of "
          f"{sum(times.values()):.0f} s); written to {LIST.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
