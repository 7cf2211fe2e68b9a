"""Per-frame diagnostics of Proposed's temporal terms (issue 50): why they gain or lose against Hu.

For each frame of a sequence under region holes, runs `fu-nonlocal` and `temporal-graph` in the paper
configuration (``variant="paper"``) and records, besides each method's whole-frame D1 (intrinsic
peak), what the temporal term of Eq. (5) sees in that frame, by wrapping the module's own
`inter_source` and `temporal_links` (nothing is changed in the method):

- ``cubes``: target cubes solved with at least one inter-source cube;
- ``new_rows``: new (hole) rows linked to an inter-source cube, counted once per neighbour frame;
- ``icp_residual``: median trimmed ICP residual of the aligned inter-source cubes to the target's
  known points, in point spacings (the motion-compensation error of the reference cube);
- ``link_new``: median distance of a new row to its linked counterpart, in point spacings (how far
  the beta terms pull the row: the dissimilarity of the matched cubes where the hole is);
- ``far_share``: share of new-row links longer than 2 point spacings (links to the hole's rim or
  to a different surface, not to the same surface point).

`python -m dpcbench.bench.reporting.temporal_diagnostics --sequence dfaust` prints the table that
docs/paper-reading.md quotes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def run(frames: list[np.ndarray], holes: dict, seed: int) -> list[dict]:
    """One record per frame (see the module docstring) for ``frames`` (list of (N, 3)) damaged by
    region holes ``holes`` (generator parameters) with ``seed``."""
    from dpcbench.holes.registry import get_generator
    from dpcbench.methods import temporal_graph as tg
    from dpcbench.methods.registry import get_method
    from dpcbench.metrics import score_frame
    from dpcbench.metrics.neighbours import point_spacing

    damage = get_generator("region", **holes).damage(frames, seed)
    spacing = float(np.median([point_spacing(f) for f in frames]))
    hu = get_method("fu-nonlocal", variant="paper").inpaint([f.copy() for f in damage.frames], damage.regions)

    log: list[dict] = []
    original_inter, original_links, original_select = tg.inter_source, tg.temporal_links, tg.select_new_points
    current = {"frame": -1, "new": 0}

    def select(*args, **kwargs):
        new = original_select(*args, **kwargs)
        current["new"] = len(new)
        return new

    def inter(*args, **kwargs):
        found = original_inter(*args, **kwargs)
        if found is not None:
            log.append({"frame": current["frame"], "kind": "inter", "residual": found.residual})
        return found

    def links(rows, aligned, *args, **kwargs):
        out = original_links(rows, aligned, *args, **kwargs)
        log.append({"frame": current["frame"], "kind": "links", "rows": len(rows), "new": current["new"],
                    "dist": np.linalg.norm(out.counterpart - rows, axis=1)})
        return out

    method = get_method("temporal-graph", variant="paper")
    assert isinstance(method, tg.TemporalGraph)  # the registry's "temporal-graph"
    configured = method._configured()
    original_frame = configured._inpaint_frame

    def frame_hook(points, *args, **kwargs):
        current["frame"] += 1
        while current["frame"] < len(frames) and not damage.regions[current["frame"]]:
            current["frame"] += 1
        return original_frame(points, *args, **kwargs)

    # the hook shadows the method on this one instance: setattr, as mypy refuses assigning to a method
    setattr(configured, "_inpaint_frame", frame_hook)  # noqa: B010
    tg.inter_source, tg.temporal_links, tg.select_new_points = inter, links, select
    try:
        proposed = configured._inpaint_sequence([f.copy() for f in damage.frames], damage.regions)[0]
    finally:
        tg.inter_source, tg.temporal_links, tg.select_new_points = original_inter, original_links, original_select

    # the rows of a cube are its m known rows, then its new rows (the last ``new`` of them)
    records = []
    for f in range(len(frames)):
        d1 = {name: score_frame(frames[f], out[f], ["gpsnr_d1"], peak="intrinsic")["gpsnr_d1"]
              for name, out in (("none", damage.frames), ("hu", hu), ("proposed", proposed))}
        residuals = [e["residual"] / spacing for e in log if e["frame"] == f and e["kind"] == "inter"]
        new_dist = []
        for e in log:
            if e["frame"] == f and e["kind"] == "links":
                new_dist.append(e["dist"][e["rows"] - e["new"]:])
        added = {name: len(out[f]) - len(damage.frames[f]) for name, out in (("hu_added", hu), ("added", proposed))}
        records.append({"frame": f, **d1, **added, "gain": d1["proposed"] - d1["hu"], "links": len(new_dist),
                        "icp_residual": float(np.median(residuals)) if residuals else float("nan"),
                        "dist": np.concatenate(new_dist) / spacing if new_dist else np.empty(0)})
    return records


def main(argv: list[str] | None = None) -> int:
    from dpcbench.bench.data.datasets import load_dataset

    parser = argparse.ArgumentParser(prog="python -m dpcbench.bench.reporting.temporal_diagnostics")
    parser.add_argument("--data-dir", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    parser.add_argument("--sequence", default="dfaust", choices=["dfaust", "samba", "human"])
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--holes", default="independent", choices=["independent", "coherent"])
    parser.add_argument("--preset", default="medium")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.sequence == "dfaust":
        frames = load_dataset(args.data_dir / "dfaust_50004_punching", frames=args.frames, progress=False).points
    elif args.sequence == "samba":
        frames = load_dataset("samba", frames=args.frames, data_dir=args.data_dir, progress=False,
                              points=100000, bit_depth=10).points
    else:
        frames = load_dataset("human", frames=args.frames, progress=False, size="tiny").points
    frames = [np.asarray(f, dtype=np.float64) for f in frames]
    records = run(frames, {"preset": args.preset, "coherent": args.holes == "coherent"}, args.seed)
    print(f"{args.sequence}, {args.frames} frames, {args.holes} {args.preset}, seed {args.seed}")
    print("| frame | none | Hu | Proposed | Proposed - Hu | linked cubes | ICP residual (sp) "
          "| new-row link median (sp) | links > 2 sp | new points Hu / Proposed |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in records:
        dist = r["dist"]
        med = float(np.median(dist)) if len(dist) else float("nan")
        far = float((dist > 2.0).mean()) if len(dist) else float("nan")
        print(f"| {r['frame']} | {r['none']:.2f} | {r['hu']:.2f} | {r['proposed']:.2f} | {r['gain']:+.2f} | "
              f"{r['links']} | {r['icp_residual']:.2f} | {med:.2f} | {far:.2f} | {r['hu_added']} / {r['added']} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
