"""Which strategy of temporal-fusion's spatial cascade filled or refused each hole of one damaged frame.

Runs `TemporalFusion.inpaint` on the damaged frame(s) of a `dpcbench damage` folder and prints, per hole region,
every strategy of `methods.temporal_fusion.spatial.CASCADE` that ran and how many points it added (0 = it refused or
found nothing open). Usage (after experiments/one_frame.sh has written OUTDIR/damaged):

    .venv/bin/python experiments/cascade_trace.py out/ld-medium/damaged [--param best_surface=false ...]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`

from dpcbench.bench.core.params import parse_params
from dpcbench.methods.temporal_fusion import spatial
from dpcbench.methods.temporal_fusion.method import TemporalFusion


def _traced(strategy, log):
    fill = strategy.fill

    def traced(cfg, hole, state):
        before = len(state.spatial) + len(state.sheet_fill)
        start = time.process_time()
        out = fill(cfg, hole, state)
        added = len(out.spatial) + len(out.sheet_fill) - before
        log.append((np.round(hole.region.center, 1).tolist(), hole.region.bounding_radius, strategy.__name__, added,
                    time.process_time() - start))
        return out

    return staticmethod(traced)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("damaged", type=Path, help="a `dpcbench damage` output folder (PLY frames + holes.json)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a temporal-fusion parameter (repeatable), e.g. best_surface=false")
    args = parser.parse_args(argv)
    loaded = load_damage_or_exit(args.damaged)
    _, frames, regions = loaded
    log: list = []
    for strategy in spatial.CASCADE:
        strategy.fill = _traced(strategy, log)
    out = TemporalFusion(**parse_params(args.param)).inpaint(frames, regions)
    for centre, radius, name, added, cpu in log:
        print(f"region at {centre} r={radius:.1f}: {name:14s} +{added:6d} points ({cpu:.1f} s CPU)")
    print(f"added {sum(len(o) - len(f) for o, f in zip(out, frames))} points in all")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
