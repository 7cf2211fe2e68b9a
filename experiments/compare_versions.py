"""Two versions of one method in one results store, row by row: whole-frame D1 / D2 / NSHD of each and of no fill,
and the paired difference (new - old) over the row's (frame, seed) pairs with its 95% interval
(`bench.results.stats.paired`: bootstrap over whole damages, a seed with all its frames, and Wilcoxon), so a change
of output is judged against noise.

    dpcbench run experiments/speed-quality.toml --store q.sqlite --executor serial     # at the old version
    dpcbench run experiments/speed-quality.toml --store q.sqlite --executor serial     # again at the new one
    .venv/bin/python experiments/compare_versions.py q.sqlite --method temporal-fusion --old 42 --new 43

A row is a sequence and its holes, generator and parameters (all its seeds, every experiment of the store); "beyond noise" when the
interval excludes 0, or with ``--decision-noise DB`` when it lies wholly beyond +-DB dB (D1 and D2; NSHD is judged
against 0 still): the frames' spread does not hold the method's decision noise, and a paired interval over frames
can exclude 0 for a change that moved only which thresholds a few points fell on
(`experiments/perturbation_noise.py` measures that noise on one damage); "inpainted frames identical" when both versions wrote the same PLY bytes in every run of the
row (the run folders must still be there). With ``--by-damage``, then every damage (a row's seed, its frames' mean)
whose D1 or D2 moved, and per row how many moved which way.
"""

from __future__ import annotations

import argparse
import hashlib
import sqlite3
from collections import defaultdict
from pathlib import Path

from dpcbench.bench.results.stats import paired

METRICS = (("gpsnr_d1", "D1"), ("gpsnr_d2", "D2"), ("nshd", "NSHD"))


def _holes(holes: str, params: str | None) -> str:
    """A row's holes as the report names them: the generator and its parameters (small and medium region holes of
    the same seeds are two rows, not one)."""
    import json

    values = json.loads(params) if params else {}
    return f"{holes}" + (f" ({', '.join(f'{k}={v}' for k, v in sorted(values.items()))})" if values else "")


def _values(connection, method: str, version: str | None) -> dict:
    """(sequence, holes) -> metric -> {(seed, frame): value} of the done runs of ``method`` (at ``version``)."""
    query = ("select r.sequence, r.holes, r.holes_params, r.seed, s.frame, s.metric, s.value from runs r "
             "join results s on s.run_id = r.run_id where r.status = 'done' and r.method = ? and s.scope = 'frame'")
    args: list = [method]
    if version is not None:
        query += " and r.method_version = ?"
        args.append(version)
    out: dict = defaultdict(lambda: defaultdict(dict))
    for sequence, holes, params, seed, frame, metric, value in connection.execute(query, args):
        out[(sequence, _holes(holes, params))][metric][(seed, frame)] = value
    return out


def _frames_digest(connection, method: str, version: str) -> dict:
    """(sequence, holes) -> sha256 over the inpainted PLY files of every done run of the row (seeds in order),
    read from the run folders: equal digests mean the two versions wrote the same bytes."""
    query = ("select sequence, holes, holes_params, seed, output_dir from runs where status = 'done' and method = ? "
             "and method_version = ? order by sequence, holes, holes_params, seed")
    digests: dict = defaultdict(hashlib.sha256)
    for sequence, holes, params, _seed, folder in connection.execute(query, (method, version)):
        for path in sorted(Path(folder, "inpainted").glob("*.ply")):
            digests[(sequence, _holes(holes, params))].update(hashlib.sha256(path.read_bytes()).digest())
    return {row: digest.hexdigest() for row, digest in digests.items()}


def _mean(values: dict) -> float:
    return sum(values.values()) / len(values) if values else float("nan")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("store")
    parser.add_argument("--method", default="temporal-fusion")
    parser.add_argument("--old", required=True, help="the old method_version")
    parser.add_argument("--new", required=True, help="the new method_version")
    parser.add_argument("--decision-noise", type=float, default=0.0, metavar="DB",
                        help="a D1 / D2 difference is beyond noise only when its interval clears +-DB (default 0)")
    parser.add_argument("--by-damage", action="store_true",
                        help="also list every damage (seed) whose D1 or D2 moved, and count them per row")
    args = parser.parse_args(argv)
    connection = sqlite3.connect(f"file:{args.store}?mode=ro", uri=True)
    old = _values(connection, args.method, args.old)
    new = _values(connection, args.method, args.new)
    none = _values(connection, "none", None)
    frames = [_frames_digest(connection, args.method, version) for version in (args.old, args.new)]
    print("| row | n | " + " | ".join(f"{label} old / new / no fill | {label} new - old [95% interval]"
                                      for _, label in METRICS) + " | inpainted frames |")
    print("|---|---|" + "---|---|" * len(METRICS) + "---|")
    for row in sorted(set(old) & set(new)):
        cells = []
        for metric, _ in METRICS:
            shared = set(new[row][metric]) & set(old[row][metric])  # the means over the pairs compared
            a, b, floor = ({key: values[key] for key in shared if key in values}
                           for values in (new[row][metric], old[row][metric], none[row][metric]))
            # new - old as it stands (no sign flip); the interval resamples whole damages (a seed, its frames)
            comparison = paired(a, b, higher_is_better=True, damage=lambda key: key[0])
            scale = 1e9 if metric == "nshd" else 1.0

            cells.append(" / ".join(f"{_mean(v) * scale:.2f}" for v in (b, a, floor)))
            if comparison.n < 2:
                cells.append(f"{comparison.mean_difference * scale:+.3f} (one pair: no interval)")
                continue
            noise = 0.0 if metric == "nshd" else args.decision_noise
            beyond = "beyond noise" if comparison.low > noise or comparison.high < -noise else "within noise"
            cells.append(f"{comparison.mean_difference * scale:+.3f} [{comparison.low * scale:+.3f}, "
                         f"{comparison.high * scale:+.3f}] {beyond}")
        n = len(set(old[row]["gpsnr_d1"]) & set(new[row]["gpsnr_d1"]))
        same = frames[0].get(row) is not None and frames[0].get(row) == frames[1].get(row)
        print(f"| {row[0]}, {row[1]} | {n} | " + " | ".join(cells) + f" | {'identical' if same else 'differ'} |")
    print("NSHD in 1e-9; n = (frame, seed) pairs; lower NSHD is better")
    if args.by_damage:
        print("\n".join(_damage_lines(old, new)))
    return 0


def _damage_lines(old: dict, new: dict) -> list[str]:
    """``--by-damage``: per row, each seed whose mean D1 or D2 over its frames differs between the versions, then the
    count of damages compared, moved, and up or down in D1 and D2."""
    lines = []
    for row in sorted(set(old) & set(new)):
        by_seed = {}
        for metric in ("gpsnr_d1", "gpsnr_d2"):
            shared = set(old[row][metric]) & set(new[row][metric])
            for seed in sorted({seed for seed, _ in shared}):
                keys = [key for key in shared if key[0] == seed]
                by_seed.setdefault(seed, []).append(
                    tuple(sum(values[key] for key in keys) / len(keys) for values in (old[row][metric], new[row][metric])))
        moved = {seed: pairs for seed, pairs in by_seed.items() if any(a != b for a, b in pairs)}
        for seed, ((d1_old, d1_new), (d2_old, d2_new)) in moved.items():
            lines.append(f"{row[0]}, {row[1]}, seed {seed}: D1 {d1_old:.2f} -> {d1_new:.2f} ({d1_new - d1_old:+.2f}), "
                         f"D2 {d2_old:.2f} -> {d2_new:.2f} ({d2_new - d2_old:+.2f})")
        counts = [sum(1 for pairs in moved.values() if sign * (pairs[i][1] - pairs[i][0]) > 0)
                  for i in (0, 1) for sign in (1, -1)]
        lines.append(f"{row[0]}, {row[1]}: {len(moved)} of {len(by_seed)} damages moved; D1 up on {counts[0]}, down on "
                     f"{counts[1]}; D2 up on {counts[2]}, down on {counts[3]}")
    return lines


if __name__ == "__main__":
    raise SystemExit(main())
