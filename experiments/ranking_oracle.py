"""How much temporal-fusion's last resort would gain from ranking its candidates by their true error.

Runs `TemporalFusion.inpaint` on a `dpcbench damage` folder twice: as it is, and with the last resort's predicted
error of each candidate (`methods._spatial_fill.best.holdout_miss`: the inner ring's RMS distance to the candidate
built without it) replaced by the candidate's true error (the RMS distance of its fill of the region to the nearest
truth point). The second is an oracle (it reads the truth), about the most a better ranking could give. The error
is used wherever the method uses the miss: to rank, in the test against the open part's predicted error, and as the
tolerance with which a later candidate continues the earlier fills. Prints whole-frame D1 / D2 (intrinsic peak,
`dpcbench score`'s) of both, per frame. Usage (after `dpcbench damage TRUTH --out DAMAGED ...`):

    .venv/bin/python experiments/ranking_oracle.py TRUTH.ply DAMAGED
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`
from fill_audit import truth_frames
from scipy.spatial import cKDTree

from dpcbench import metrics
from dpcbench.bench.data.plyio import read_ply
from dpcbench.methods._spatial_fill import best
from dpcbench.methods.temporal_fusion.method import TemporalFusion


def true_error_ranking(truth: cKDTree):
    """A stand-in for `best.holdout_miss` that returns the candidate's true error against ``truth``."""

    def miss(candidate, region, ring) -> float:
        support, fill = candidate
        points = fill(support, region, None)
        if not len(points):
            return float("inf")
        return float(np.sqrt(np.mean(truth.query(points)[0] ** 2)))

    return miss


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("truth", type=Path, help="the ground-truth PLY frame (or folder of frames)")
    parser.add_argument("damaged", type=Path, help="the `dpcbench damage` output folder")
    args = parser.parse_args(argv)
    _, frames, regions = load_damage_or_exit(args.damaged)
    truths = [np.asarray(read_ply(p, colors=False).points, dtype=np.float64)
              for p in truth_frames(args.truth, args.damaged)]
    default_miss = best.holdout_miss
    rows = {}
    for label in ("hold-out miss (the method)", "true error (oracle)"):
        outputs = []
        for f, frame in enumerate(frames):
            best.holdout_miss = default_miss if label.startswith("hold") else true_error_ranking(cKDTree(truths[f]))
            try:
                outputs.append(TemporalFusion().inpaint([frame], [regions[f]])[0])
            finally:
                best.holdout_miss = default_miss
        rows[label] = [metrics.score_frame(t, o, ["gpsnr_d1", "gpsnr_d2"]) for t, o in zip(truths, outputs)]
    for label, scores in rows.items():
        print(label, " ".join(f"frame {f}: D1 {s['gpsnr_d1']:.2f} D2 {s['gpsnr_d2']:.2f}" for f, s in enumerate(scores)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
