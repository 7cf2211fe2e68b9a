"""Quality yardstick of ``detect_holes``: synthetic holes punched into stand-ins and real frames, scored
against the truth. A change to the detector is adopted only if it does not score worse here.

    python tests/benchmarks/detect_holes_quality.py                          # the current code
    python tests/benchmarks/detect_holes_quality.py --revision 51eab50       # holes/detection.py at a revision
    python tests/benchmarks/detect_holes_quality.py --frames human:small,dfaust --seeds 0 --json out.json

Frames (``--frames``, comma-separated): ``human:SIZE`` / ``bunny:SIZE`` (embedded stand-ins, frame 0),
``dfaust`` (frame 0 of /work/shared/data/dfaust_50004_punching, 100k points, not voxelized),
``longdress`` (/work/shared/data/8i_longdress_1300, 858k points, 10-bit). The real frames are found
under ``--data`` (default: ``$DPCBENCH_DATA_DIR`` or ../shared/data beside the repository).
Damage: the ``region`` generator (ball holes), every preset of ``--presets`` x every seed of ``--seeds``;
or with ``--generator occlusion`` the occlusion generator's default rig per seed (the holes of the
real-hole protocol; pass its detection parameters with ``--param``, e.g. those of
`bench.reporting.paper.STANDIN_DETECTION`: ``--param gap=1.5707963267948966 --param min_points=5 --param min_inward=0``).

Scores, per damaged frame (``detect_holes`` with ``--param`` keyword arguments, else its defaults):

- **recall**: true holes matched / true holes. A detected region matches a true hole by the rule of
  `holes.detection.detection_scores`: its centre lies in the hole, or it contains at least half of
  the hole's removed points.
- **precision**: detected regions matching a true hole / (those + spurious ones). Real captures have
  holes of their own (Longdress: under the arms, the hair), so the detector is also run on the
  undamaged frame; a detected region that matches no true hole but overlaps a region detected on the
  undamaged frame (either's centre inside the other) is a *natural* hole, counted apart and left out
  of precision. A region matching neither is *spurious*. (On the closed stand-ins nothing is detected
  on the undamaged frame, so this reduces to detection_scores' precision.)
- **boundary recall**: of the true rim band (damaged-frame points within 1.5 point spacings of a
  removed point), the fraction that `boundary_points` flags.
- **boundary precision**: of the points flagged on the damaged frame but not on the undamaged one
  (same point, same k and gap), the fraction within 3 point spacings of a removed point.

Totals are pooled (sums of counts over frames, not means of ratios). ``--json`` writes every
per-frame record and the totals, so that two runs (before / after a change) can be compared with
``--compare A.json B.json``, which prints the totals side by side and the frames whose detected
regions differ: count of regions per frame, how many regions of A have no identical region in B
(centre and radius equal to 1e-9), and how many are *gone* (no region of B centred within half the
A region's radius).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

DEFAULT_FRAMES = "human:small,bunny:small,dfaust,human:default,bunny:default,longdress"


def load_detection(revision: str | None):
    """holes/detection.py at git ``revision`` as a module (None: the installed current one)."""
    if revision is None:
        from dpcbench.holes import detection

        return detection
    source = subprocess.run(["git", "-C", str(REPO), "show", f"{revision}:holes/detection.py"],
                            check=True, capture_output=True, text=True).stdout
    spec = importlib.util.spec_from_loader(f"detection_{revision}", loader=None)
    module = importlib.util.module_from_spec(spec)
    exec(compile(source, f"{revision}:holes/detection.py", "exec"), module.__dict__)
    return module


def data_dir(given: str | None) -> Path:
    if given:
        return Path(given)
    if os.environ.get("DPCBENCH_DATA_DIR"):
        return Path(os.environ["DPCBENCH_DATA_DIR"])
    return REPO.parent / "shared" / "data"


def load_frame(item: str, data: Path) -> np.ndarray:
    """The (N, 3) float64 frame named by ``item`` (see the module docstring)."""
    if item == "dfaust":
        from dpcbench.bench.data.sequences import load_sequence

        return np.asarray(load_sequence(data / "dfaust_50004_punching", colors=False).points[0], dtype=np.float64)
    if item == "longdress":
        from dpcbench.bench.data.plyio import read_ply

        return np.asarray(read_ply(data / "8i_longdress_1300" / "longdress_vox10_1300.ply").points, dtype=np.float64)
    from dpcbench.bench.data.datasets import load_dataset

    name, _, size = item.partition(":")
    return np.asarray(load_dataset(name, frames=1, seed=0, size=size or "small", progress=False).points[0],
                      dtype=np.float64)


def region_record(region) -> list:
    return [*map(float, region.center), float(region.radius)]


def score_frame(detection, params: dict, original: np.ndarray, removed: np.ndarray, truth: list,
                natural: list, natural_mask: np.ndarray) -> dict:
    """Scores of one damaged frame ``original[~removed]`` (see the module docstring)."""
    from scipy.spatial import cKDTree

    from dpcbench.metrics.neighbours import point_spacing

    damaged = original[~removed]
    removed_pts = original[removed]
    start, start_cpu = time.perf_counter(), time.process_time()
    detected = detection.detect_holes(damaged, **params)
    wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    # match matrix by detection_scores' rule
    match = np.zeros((len(detected), len(truth)), dtype=bool)
    for j, hole in enumerate(truth):
        hole_pts = removed_pts[hole.contains(removed_pts)]
        for i, det in enumerate(detected):
            covered = len(hole_pts) > 0 and det.contains(hole_pts).mean() >= 0.5
            match[i, j] = bool(hole.contains(det.center[None, :])[0]) or covered
    is_true = match.any(axis=1)
    is_natural = np.array([not is_true[i] and any(
        n.contains(det.center[None, :])[0] or det.contains(n.center[None, :])[0] for n in natural)
        for i, det in enumerate(detected)], dtype=bool)
    # boundary points
    spacing = point_spacing(original)
    gap_kw = {key: params[key] for key in ("k", "gap") if key in params}
    mask = detection.boundary_points(damaged, interior_values=False, **gap_kw)[0]
    dist, _ = cKDTree(removed_pts).query(damaged, k=1, distance_upper_bound=3.5 * spacing)
    band = dist <= 1.5 * spacing
    new_flags = mask & ~natural_mask[~removed]
    return {
        "true_holes": len(truth), "found": int(match.any(axis=0).sum()),
        "detected": len(detected), "correct": int(is_true.sum()), "natural": int(is_natural.sum()),
        "spurious": int((~is_true & ~is_natural).sum()),
        "band": int(band.sum()), "band_flagged": int((band & mask).sum()),
        "new_flags": int(new_flags.sum()), "new_flags_near": int((new_flags & (dist <= 3 * spacing)).sum()),
        "regions": [region_record(r) for r in detected], "wall_s": wall, "cpu_s": cpu,
    }


def totals(records: list[dict]) -> dict:
    s = {key: sum(r[key] for r in records) for key in
         ("true_holes", "found", "detected", "correct", "natural", "spurious", "band", "band_flagged",
          "new_flags", "new_flags_near", "cpu_s")}
    s["recall"] = s["found"] / s["true_holes"] if s["true_holes"] else 1.0
    s["precision"] = s["correct"] / (s["correct"] + s["spurious"]) if s["correct"] + s["spurious"] else 1.0
    s["boundary_recall"] = s["band_flagged"] / s["band"] if s["band"] else 1.0
    s["boundary_precision"] = s["new_flags_near"] / s["new_flags"] if s["new_flags"] else 1.0
    return s


def line(label: str, t: dict) -> str:
    return (f"{label:<22} holes {t['found']:>3}/{t['true_holes']:<3} recall {t['recall']:.3f} | regions "
            f"{t['detected']:>3} (true {t['correct']}, natural {t['natural']}, spurious {t['spurious']}) "
            f"precision {t['precision']:.3f} | boundary recall {t['boundary_recall']:.3f} "
            f"precision {t['boundary_precision']:.3f} | detect CPU {t['cpu_s']:.1f} s")


def run(args) -> dict:
    from dpcbench.holes.registry import get_generator

    detection = load_detection(args.revision)
    params = {}
    for item in args.param:
        key, _, value = item.partition("=")
        params[key] = json.loads(value)
    data = data_dir(args.data)
    seeds = [int(s) for s in args.seeds.split(",")]
    presets = args.presets.split(",")
    records = []
    print(f"detection: {args.revision or 'current'} params {params} | load average {os.getloadavg()[0]:.2f}",
          flush=True)
    for item in args.frames.split(","):
        original = load_frame(item, data)
        gap_kw = {key: params[key] for key in ("k", "gap") if key in params}
        natural = detection.detect_holes(original, **params)
        natural_mask = detection.boundary_points(original, interior_values=False, **gap_kw)[0]
        frame_records = []
        for preset in (presets if args.generator == "region" else ["-"]):
            for seed in seeds:
                gen = get_generator("region", preset=preset) if args.generator == "region" else get_generator(
                    args.generator)
                res = gen.damage([original], seed)
                rec = score_frame(detection, params, original, res.removed[0], res.regions[0], natural,
                                  natural_mask)
                rec.update(frame=item, preset=preset, seed=seed, points=len(original))
                frame_records.append(rec)
        records += frame_records
        print(line(f"{item} ({len(original):,})", totals(frame_records)) + f" | undamaged: {len(natural)} regions",
              flush=True)
    out = {"revision": args.revision, "params": params, "records": records, "totals": totals(records)}
    print(line("ALL", out["totals"]))
    print(f"load average {os.getloadavg()[0]:.2f} at end")
    if args.json:
        Path(args.json).write_text(json.dumps(out))
    return out


def compare(a_path: str, b_path: str) -> None:
    a, b = (json.loads(Path(p).read_text()) for p in (a_path, b_path))
    print(line("A " + str(a["revision"] or "current") + str(a["params"] or ""), a["totals"]))
    print(line("B " + str(b["revision"] or "current") + str(b["params"] or ""), b["totals"]))
    changed = total = gone = 0
    for ra, rb in zip(a["records"], b["records"]):
        assert (ra["frame"], ra["preset"], ra["seed"]) == (rb["frame"], rb["preset"], rb["seed"])
        same = sum(any(np.allclose(x, y, rtol=0, atol=1e-9) for y in rb["regions"]) for x in ra["regions"])
        # a region of A "gone" from B: no region of B has its centre within half A's radius
        missing = sum(not any(np.linalg.norm(np.subtract(x[:3], y[:3])) <= x[3] / 2 for y in rb["regions"])
                      for x in ra["regions"])
        total += len(ra["regions"])
        gone += missing
        if same != len(ra["regions"]) or len(ra["regions"]) != len(rb["regions"]):
            changed += 1
            print(f"  {ra['frame']} {ra['preset']} seed {ra['seed']}: regions {len(ra['regions'])} -> "
                  f"{len(rb['regions'])}, {len(ra['regions']) - same} of A's not identical in B, {missing} gone "
                  f"(no B centre within half its radius); found {ra['found']} -> {rb['found']}, spurious "
                  f"{ra['spurious']} -> {rb['spurious']}")
    print(f"{changed} of {len(a['records'])} damaged frames have different regions; of A's {total} regions, "
          f"{gone} have no B region near (centre within half the radius)")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", default=DEFAULT_FRAMES)
    parser.add_argument("--presets", default="small,medium,large")
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--generator", default="region", choices=["region", "occlusion"],
                        help="hole generator (occlusion: acquisition-like holes, default rig; --presets unused)")
    parser.add_argument("--revision", default=None, help="git revision of holes/detection.py (default: current)")
    parser.add_argument("--param", action="append", default=[], help="detect_holes keyword, e.g. k=20 (JSON value)")
    parser.add_argument("--data", default=None, help="folder holding dfaust_50004_punching and 8i_longdress_1300")
    parser.add_argument("--json", default=None, help="write the per-frame records and totals here")
    parser.add_argument("--compare", nargs=2, metavar=("A.json", "B.json"), help="compare two --json outputs")
    args = parser.parse_args(argv)
    if args.compare:
        compare(*args.compare)
    else:
        run(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
