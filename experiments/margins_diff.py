"""Two margins files of one method side by side: the rows whose verdict differs, and each target's count in both.

`dpcbench margins ... --out DIR` writes DIR/margins.csv (one line per row and target). Given two such folders (the
same presets run at two code versions, on two machines, or pinned to one instruction set and not), this prints per
target "met on k of n rows" in each and the largest change of a row's margin, then every row where one file meets
the target and the other does not, or where one says "beyond noise" and the other not, with both margins and
intervals.

    .venv/bin/python experiments/margins_diff.py results/margins/temporal-fusion-57 \
        results/margins/temporal-fusion-57-pinned
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

KEY = ["role", "experiment", "row", "target"]


def read(folder: Path) -> pd.DataFrame:
    path = folder / "margins.csv"
    if not path.is_file():
        sys.exit(f"{path}: no such file; give folders written by dpcbench margins --out")
    table = pd.read_csv(path)
    return table[table["margin"].notna()]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("first", type=Path)
    parser.add_argument("second", type=Path)
    args = parser.parse_args()
    first, second = read(args.first), read(args.second)
    both = first.merge(second, on=KEY, suffixes=("_1", "_2"))
    print(f"{len(both)} (row, target) pairs in both files; {len(first) - len(both)} only in the first, "
          f"{len(second) - len(both)} only in the second")
    for (role, target), block in both.groupby(["role", "target"], sort=True):
        moved = (block["margin_2"] - block["margin_1"]).abs()
        worst = block.loc[moved.idxmax()]
        print(f"{role:8s} {target:10s} met on {int(block['met_1'].sum())} / {int(block['met_2'].sum())} of {len(block)} "
              f"rows (first / second); margins moved by at most {moved.max():.3g} ({worst['row']})")
    changed = both[(both["met_1"] != both["met_2"]) | (both["verdict_1"] != both["verdict_2"])]
    print(f"\n{len(changed)} verdicts differ:")
    for _, r in changed.iterrows():
        print(f"- {r['role']} {r['experiment']} | {r['row']} | {r['target']}: "
              f"{r['margin_1']:+.2f} [{r['low_1']:+.2f}, {r['high_1']:+.2f}] vs {r['against_1']} ({r['verdict_1']}) -> "
              f"{r['margin_2']:+.2f} [{r['low_2']:+.2f}, {r['high_2']:+.2f}] vs {r['against_2']} ({r['verdict_2']})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
