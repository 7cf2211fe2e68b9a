"""Golden output hashes of `temporal-fusion`: a sha256 of the exact output points per case, so a refactoring
can show that it leaves every output bit-identical.

    .venv/bin/python experiments/fusion_golden.py            # compute, compare with fusion_golden.json
    .venv/bin/python experiments/fusion_golden.py --write    # record the hashes (only at a trusted state)
    .venv/bin/python experiments/fusion_golden.py --coloured # the same hashes through inpaint_with_colours
    .venv/bin/python experiments/fusion_golden.py --against main  # compare with revision main run on this machine

Cases (about 4 CPU minutes in all): the embedded stand-ins at size "tiny" (the human and the bunny, 10-bit
voxels, and the bunny sampled unvoxelized) with independent and coherent medium region holes and occlusion holes
(`holes/`, seed 0, 3 frames), a one-frame case, a blind case (regions=None: `detect_holes` per frame), and
3 frames of D-FAUST punching when ../shared/data holds it (skipped otherwise). The defaults run on every case;
each switch of `TemporalFusion`, flipped once, runs on the cheap voxelized cases and the float coherent case.
The hash is over, per frame, the output's shape and its float64 bytes in row order. With ``--coloured`` every case
runs through ``inpaint_with_colours`` (the colour-tracking path; the stand-ins' own colours, a colour made from the
coordinates where a sequence has none) and its geometry must hash as ``inpaint``'s does.
Exit status 1 when a hash differs from the recorded one.

The hashes hold on the CPU they were recorded on: the last bits of the fills' linear algebra differ between CPUs,
and the method's thresholds turn them into other points (recorded on one machine, 6 of the 122 matched on an AMD
EPYC machine, pinned by .ci/pinned-isa or not, at the commit that wrote them). ``--against REV`` runs the same cases
with the package of git revision REV (a temporary worktree) on this machine and compares with that instead: what a
refactoring must leave unchanged."""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).with_suffix(".json")
DFAUST = ROOT.parent / "shared" / "data" / "dfaust_50004_punching"

#: each keyword flipped once (booleans negated; the others set to a non-default value that is cheap)
FLIPS: dict[str, object] = {name: None for name in (
    "refine", "deform", "reuse_previous", "fallback", "rim_fill", "poisson", "poisson_bodies", "poisson_bridges",
    "cap", "harmonic_cap", "walled_cap_first", "membrane", "front", "partial_sources", "sheet", "revoxelize",
    "pool_adjacent", "adjacent_first", "count_copies", "reuse_next", "drop_layers", "coarse_retry",
    "poisson_in_boxes", "membrane_after_poisson")}
FLIPS.update(window=1, mls_neighbours=20, snap=False)


def digest(outputs: list[np.ndarray]) -> str:
    h = hashlib.sha256()
    for points in outputs:
        points = np.ascontiguousarray(points, dtype=np.float64)
        h.update(repr(points.shape).encode())
        h.update(points.tobytes())
    return h.hexdigest()


def _coordinate_colours(frames: list[np.ndarray]) -> list[np.ndarray]:
    """A deterministic colour per point made from its coordinates (for sequences without colour)."""
    return [(np.abs(np.floor(f * 37.0)) % 256).astype(np.uint8) for f in frames]


def inputs() -> dict[str, tuple[list[np.ndarray], list | None, list[np.ndarray]]]:
    """case name -> (damaged frames, regions or None, damaged colours)."""
    from dpcbench.bench.data.standins import bunny, human
    from dpcbench.holes.registry import get_generator

    sequences = {
        "human-tiny": [human.generate_frame(i, size="tiny")[:2] for i in range(3)],
        "bunny-tiny": [bunny.generate_frame(i, size="tiny")[:2] for i in range(3)],
        "bunny-tiny-float": [bunny.generate_frame(i, size="tiny", bit_depth=None)[:2] for i in range(3)],
    }
    holes = {
        "independent": ("region", dict(preset="medium")),
        "coherent": ("region", dict(preset="medium", coherent=True)),
        # the default stage rig leaves the tiny stand-ins all but whole: three cameras a ring, no cover rule
        "occlusion": ("occlusion", dict(per_ring=3, seen_within=0)),
    }
    cases = {}
    for seq_name, pairs in sequences.items():
        frames, colours = [p for p, _ in pairs], [c for _, c in pairs]
        for hole_name, (generator, params) in holes.items():
            damage = get_generator(generator, **params).damage(frames, 0, colors=colours)
            cases[f"{seq_name}/{hole_name}"] = (damage.frames, damage.regions, damage.colors)
    frames, regions, colours = cases["human-tiny/independent"]
    cases["human-tiny/one-frame"] = (frames[:1], regions[:1], colours[:1])
    cases["human-tiny/blind"] = (frames, None, colours)
    frames, _, colours = cases["bunny-tiny-float/coherent"]
    cases["bunny-tiny-float/blind"] = (frames, None, colours)
    if DFAUST.is_dir():
        from dpcbench.bench.data.sequences import load_sequence

        seq = load_sequence(DFAUST, colors=False)
        frames = [np.asarray(f.points, dtype=np.float64) for f in seq.frames[:3]]
        for hole_name in ("independent", "coherent"):
            generator, params = holes[hole_name]
            damage = get_generator(generator, **params).damage(frames, 0)
            cases[f"dfaust-punching/{hole_name}"] = (damage.frames, damage.regions,
                                                     _coordinate_colours(damage.frames))
    return cases


#: the cases each flip runs on: cheap ones that reach every step (voxel gaps, copies, reuse, boxes, float data)
FLIP_CASES = ("human-tiny/independent", "human-tiny/coherent", "human-tiny/occlusion", "bunny-tiny-float/coherent")


def run(only: str | None = None, coloured: bool = False) -> dict[str, str]:
    from dpcbench.methods.temporal_fusion import TemporalFusion

    cases = inputs()
    jobs = [(f"{name} defaults", name, {}) for name in cases]
    jobs += [(f"{name} {key}={value if value is not None else 'flipped'}", name, {key: value})
             for key, value in FLIPS.items() for name in FLIP_CASES]
    hashes = {}
    for label, case, params in jobs:
        if only and only not in label:
            continue
        frames, regions, colours = cases[case]
        params = {key: (not TemporalFusion().get_params()[key]) if value is None else value
                  for key, value in params.items()}
        start = time.process_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            method = TemporalFusion(**params)
            if coloured:
                outputs, _ = method.inpaint_with_colours([f.copy() for f in frames], colours, regions)
            else:
                outputs = method.inpaint([f.copy() for f in frames], regions)
        hashes[label] = digest(outputs)
        added = sum(len(o) for o in outputs) - sum(len(f) for f in frames)
        print(f"{hashes[label][:16]}  {label}  (+{added} points, {time.process_time() - start:.1f} s CPU)", flush=True)
    return hashes



def hashes_at(revision: str, only: str | None, coloured: bool) -> dict[str, str]:
    """The hashes of this script's cases computed by the package of git ``revision`` on this machine
    (`_revision.package_of`), in a child process that runs this file's `run`, so both sides run the same cases and
    flips."""
    from _revision import package_of

    with package_of(revision) as env, tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "hashes.json"
        child = [sys.executable, __file__, "--json-out", str(out)] + (["--only", only] if only else [])
        subprocess.run(child + (["--coloured"] if coloured else []), check=True, env=env)
        return json.loads(out.read_text(encoding="utf-8"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", action="store_true", help="record the hashes in fusion_golden.json")
    parser.add_argument("--only", help="run only the cases whose label contains this text")
    parser.add_argument("--coloured", action="store_true",
                        help="run through inpaint_with_colours (the geometry must hash the same)")
    parser.add_argument("--against", metavar="REV",
                        help="compare with the hashes of git revision REV computed on this machine, not the record")
    parser.add_argument("--json-out", type=Path, help=argparse.SUPPRESS)  # --against's child writes its hashes here
    args = parser.parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    if args.write and (args.coloured or args.against):
        parser.error("--write records inpaint's hashes at this tree: run it without --coloured or --against")
    hashes = run(args.only, args.coloured)
    if args.json_out:
        args.json_out.write_text(json.dumps(hashes), encoding="utf-8")
        return 0
    if args.write:
        if args.only and GOLDEN.is_file():  # a subset is added to (or replaces its entries in) the record
            hashes = {**json.loads(GOLDEN.read_text(encoding="utf-8")), **hashes}
        GOLDEN.write_text(json.dumps(hashes, indent=1, sort_keys=True) + "\n", encoding="utf-8")
        print(f"wrote {len(hashes)} hashes to {GOLDEN.relative_to(ROOT)}")
        return 0
    if args.against:
        print(f"the same cases at {args.against}:", flush=True)
        recorded = hashes_at(args.against, args.only, args.coloured)
    elif not GOLDEN.is_file():
        print(f"no {GOLDEN.name} yet: run with --write at a trusted state", file=sys.stderr)
        return 2
    else:
        recorded = json.loads(GOLDEN.read_text(encoding="utf-8"))
    differ = [label for label in hashes if label in recorded and recorded[label] != hashes[label]]
    missing = [label for label in hashes if label not in recorded]
    for label in differ:
        print(f"DIFFERS: {label}")
    for label in missing:
        print(f"not recorded: {label}")
    print(f"{len(hashes) - len(differ) - len(missing)} of {len(hashes)} hashes match")
    return 1 if differ or missing else 0


if __name__ == "__main__":
    sys.exit(main())
