"""Whether the closed surface's first look one octree level coarser (`methods._spatial_fill.poisson._holds_out`,
temporal-fusion 51) ever decides a hold-out otherwise than the hold-out's own surface alone (version 50): every
hold-out of temporal-fusion's runs of the given presets is judged both ways.

    .venv/bin/python experiments/coarse_look_check.py temporal-fusion-targets temporal-fusion-heldout \
        temporal-fusion-heldout-frames temporal-fusion-heldout-framerate temporal-fusion-heldout-data \
        temporal-fusion-heldout-frame [--jobs 2]

A preset may name the runs to check by their index among its temporal-fusion runs (`--list` prints them), as
``PRESET:A-B,C``: ``temporal-fusion-targets:11-16,20`` checks runs 11 to 16 and 20.

Each run's damage is made as the runner makes it (the preset's sequence, generator, seed); temporal-fusion runs with
the preset's parameters, and each `_holds_out` call is made twice: as the method makes it, and with the first look
switched off (`COARSE_LOOK_MIN_DEPTH` out of reach). Prints per run the hold-outs, how many the first look decided
(refused, passed) and how many of those the hold-out's own surface decides otherwise; then the totals. No
disagreement means the run's output is that of version 50, since the output depends on the hold-outs only through
their decisions. Exit status 1 on a disagreement.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from dpcbench.bench.data.datasets import load_run_sequence
from dpcbench.bench.execution.worker import import_entry
from dpcbench.bench.experiment.config import expand_config, load_config
from dpcbench.methods._spatial_fill import poisson

PRESETS = Path(__file__).resolve().parents[1] / "bench" / "presets"


_JUDGED: list = []  # this process's hold-outs since `check_run` began: (first look decided: None, "refused", "passed"; agrees)


def _judge_both_ways() -> None:
    """Wrap `poisson._holds_out` (once a process: a pool worker checks many runs): each call appends to `_JUDGED`.
    The first look decided a call when the call never reconstructed at the depth version 50 reconstructs at
    (the depths are traced at `poisson.poisson_mesh`, so the hold-out's own guards are not repeated here)."""
    if getattr(poisson._holds_out, "judged_both_ways", False):
        return
    holds_out, poisson_mesh = poisson._holds_out, poisson.poisson_mesh
    depths: list[int] = []

    def traced_mesh(cloud, depth):
        depths.append(depth)
        return poisson_mesh(cloud, depth)

    def traced(*args):
        depths.clear()
        passed = holds_out(*args)
        looked_at = set(depths)
        depth_rule = poisson.COARSE_LOOK_MIN_DEPTH
        poisson.COARSE_LOOK_MIN_DEPTH = 10 ** 6  # version 50: the hold-out's own surface alone
        depths.clear()
        try:
            alone = holds_out(*args)
        finally:
            poisson.COARSE_LOOK_MIN_DEPTH = depth_rule
        decided_first = bool(depths) and not looked_at & set(depths)
        _JUDGED.append((("passed" if passed else "refused") if decided_first else None, passed == alone))
        return passed

    traced.judged_both_ways = True  # type: ignore[attr-defined]
    poisson.poisson_mesh = traced_mesh
    poisson._holds_out = traced


def _selected(name: str) -> list:
    """(index, run spec) of the temporal-fusion runs of ``name`` (a preset, an experiment TOML, either with
    ``:A-B,C``)."""
    name, _, picks = name.partition(":")
    path = Path(name) if name.endswith(".toml") else PRESETS / f"{name}.toml"
    specs = [s for s in expand_config(load_config(path)) if s.method["name"] == "temporal-fusion"]
    if not picks:
        return list(enumerate(specs))
    chosen: list[int] = []
    for pick in picks.split(","):
        first, _, last = pick.partition("-")
        chosen += range(int(first), int(last or first) + 1)
    if max(chosen) >= len(specs):
        raise SystemExit(f"{name} has {len(specs)} temporal-fusion runs (0-{len(specs) - 1}); pick among them")
    return [(i, specs[i]) for i in chosen]


def _label(spec) -> str:
    return f"{spec.sequence.get('label', '')} {spec.holes['generator']} {spec.holes['params']} seed {spec.holes['seed']}"


def check_run(spec) -> tuple[str, int, int, int, int]:
    """(label, hold-outs, decided by the first look as refused, as passed, disagreements) of one run spec."""
    _judge_both_ways()
    _JUDGED.clear()
    truth = load_run_sequence(spec.sequence)
    generator = import_entry(spec.holes["entry"])(**spec.holes["params"])
    damage = generator.damage(truth.points, spec.holes["seed"])
    method = import_entry(spec.method["entry"])(**spec.method["params"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        method.inpaint([f.copy() for f in damage.frames], damage.regions)
    log = list(_JUDGED)
    return (_label(spec), len(log), sum(d == "refused" for d, _ in log), sum(d == "passed" for d, _ in log),
            sum(not agrees for _, agrees in log))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("presets", nargs="+", help="preset names (bench/presets) or experiment TOML files")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--list", action="store_true", help="print the runs' indices and labels, check none")
    args = parser.parse_args(argv)
    specs = []
    for name in args.presets:
        chosen = _selected(name)
        if args.list:
            print("\n".join(f"{name.partition(':')[0]} {i}: {_label(spec)}" for i, spec in chosen))
        specs += [spec for _, spec in chosen]
    if args.list:
        return 0
    totals = [0, 0, 0, 0]
    with ProcessPoolExecutor(args.jobs) as pool:
        for label, *counts in pool.map(check_run, specs):
            print(f"{label}: {counts[0]} hold-outs, first look refused {counts[1]}, passed {counts[2]}, "
                  f"disagreements {counts[3]}", flush=True)
            totals = [a + b for a, b in zip(totals, counts)]
    print(f"{len(specs)} runs: {totals[0]} hold-outs, the first look decided {totals[1] + totals[2]} "
          f"({totals[1]} refused, {totals[2]} passed), disagreements {totals[3]}")
    return 1 if totals[3] else 0


if __name__ == "__main__":
    sys.exit(main())
