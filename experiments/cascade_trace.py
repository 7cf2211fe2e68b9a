"""Which strategy of temporal-fusion's spatial cascade filled or refused each hole of one damaged frame.

Runs `TemporalFusion.inpaint` on the damaged frame(s) of a `dpcbench damage` folder and prints, per hole region,
every strategy of `methods.temporal_fusion.spatial.CASCADE` that ran and how many points it added (0 = it refused or
found nothing open). With ``--holdouts``, before each strategy's line, every hold-out it judged, the fill named on each
line (step 6c's closed surface, `poisson._holds_out`; step 6c's tube and step 6e's membrane, the shared rule
`methods._spatial_fill.common.holdout_passes`): the held-out points, their RMS miss m, their own scatter e,
sqrt(m^2 - e^2) and the bound, in coordinate units, and the decision. With ``--membrane R``, for each membrane
(step 6e, `membrane_fill`) of a region of bounding radius R or more, how many of its seeds and anchors each of its
tests keeps, in run order (`_traced_membrane`): where a large occlusion box ends up mostly open, this says which
test took the rest. Usage (after experiments/one_frame.sh has written OUTDIR/damaged, or after `dpcbench damage`):

    .venv/bin/python experiments/cascade_trace.py out/ld-medium/damaged [--holdouts] [--membrane 60]
        [--param best_surface=false ...]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`
from scipy.spatial import cKDTree

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


def _traced_holdouts(log):
    """Wrap every hold-out where the fills call it, each call logged with its fill's name and its figures: the shared
    rule (`methods._spatial_fill.common.holdout_passes`) where step 6e's membrane and step 6c's tube call it, and
    step 6c's closed-surface test (`poisson._holds_out`, its own capped distances and a coarser first look)."""
    from dpcbench.methods._spatial_fill import membrane, poisson
    from dpcbench.methods._spatial_fill.common import holdout_passes, own_scatter_sq

    def line(fill, count, miss, scatter, bound, passed, note=""):
        net = float(np.sqrt(max(miss ** 2 - scatter ** 2, 0.0)))
        return (f"  hold-out ({fill}): {count} held-out points, miss {miss:.3f}, scatter {scatter:.3f}, net {net:.3f}, "
                f"bound {bound:.3f}{note}: {'passed' if passed else 'refused'}")

    def shared(fill):
        def traced(offsets, held, support, bound):
            passed = holdout_passes(offsets, held, support, bound)
            if len(offsets):
                miss = float(np.sqrt(np.mean(np.square(offsets))))
                log.append(line(fill, len(offsets), miss, float(np.sqrt(own_scatter_sq(held, support))), bound, passed))
            return passed
        return traced

    holds_out = poisson._holds_out

    def closed_surface(support, region, ring, spacing, grid, max_holdout_spacings):
        passed = holds_out(support, region, ring, spacing, grid, max_holdout_spacings)
        inner = region.contains(support, margin=ring)
        if inner.sum() >= 6 and (~inner).sum() >= 32:
            # the miss in full, on the held-out surface at its own depth (the test itself may have decided on a
            # coarser look first, or on distances capped far beyond the bound)
            cloud, depth = poisson.poisson_input(support[~inner], grid, poisson.POISSON_HOLDOUT_CELL_STEPS)
            samples = poisson._mesh_samples(poisson.poisson_mesh(cloud, depth), grid, (region, ring))
            samples = samples[region.contains(samples, margin=ring)]
            distance = (cKDTree(samples).query(support[inner])[0] if len(samples)
                        else np.full(int(inner.sum()), np.inf))
            log.append(line("closed surface", int(inner.sum()), float(np.sqrt(np.mean(distance ** 2))),
                            float(np.sqrt(own_scatter_sq(support[inner], support))), max_holdout_spacings * spacing,
                            passed, f", ring {ring:.3f} wide"))
        return passed

    membrane.holdout_passes = shared("membrane")
    poisson.holdout_passes = shared("tube")
    poisson._holds_out = closed_surface


def _traced_membrane(log, least_radius: float) -> None:
    """Wrap step 6e's membrane (`membrane_fill`, where `spatial` calls it) and the functions it calls in its own
    module's namespace, so that each membrane of a region of bounding radius ``least_radius`` or more logs, in run
    order, what each of its tests kept: its seeds and anchors (`LozesPDE.seed_hole`), the height-field test's share of
    steep anchors (`fit_height_field`, against its bound ``max_steep``), the retry on the hole's sheet
    (`_flat_anchors`, `_sheet_bounded`), the sag (`membrane_sag`, against the hold-out bound) and the hull rule
    (`_within_hull_of`), the hold-out (`holdout_passes`), the evolved points, the agreement and layer rules
    (`grown_agreeing`, `between_layers`), the points not already covered (`far_from`), and how far the returned points
    spread (the grid cells of 1 unit they round to, the voxels on voxelized data, and their median nearest-neighbour
    distance)."""
    from dpcbench.methods._spatial_fill import membrane
    from dpcbench.methods.lozes_pde import LozesPDE

    tracing = [False]
    labels = {
        "fit_height_field": lambda args, out: f"height field: {out[4]:.1%} of {len(args[0])} anchors steep",
        "_flat_anchors": lambda args, out: f"flat anchors (the hole's sheet): {int(out.sum())} of {len(out)}",
        "_sheet_bounded": lambda args, out: f"seeds bordering the sheet more than the crossing: {int(out.sum())} of {len(out)}",
        "membrane_sag": lambda args, out: f"sag {out:.3f}",
        "_within_hull_of": lambda args, out: f"seeds within the hull of the captured points: {int(out.sum())} of {len(out)}",
        "holdout_passes": lambda args, out: f"hold-out: {'passed' if out else 'refused'} ({len(args[0])} held-out points)",
        "grown_agreeing": lambda args, out: f"agreeing with the anchors' local surface: {int(out.sum())} of {len(out)}",
        "between_layers": lambda args, out: f"between two layers (dropped): {int(out.sum())} of {len(out)}",
        "far_from": lambda args, out: f"not covered already: {int(out.sum())} of {len(out)}",
    }

    def wrapped(name, function):
        def traced(*args, **kwargs):
            out = function(*args, **kwargs)
            if tracing[0]:
                log.append("    membrane, " + labels[name](args, out))
            return out
        return traced

    for name in labels:
        setattr(membrane, name, wrapped(name, getattr(membrane, name)))
    seed_hole, evolve = LozesPDE.seed_hole, LozesPDE.evolve

    def traced_seed_hole(self, points, region, step):
        seeds, anchors = seed_hole(self, points, region, step)
        if tracing[0]:
            log.append(f"    membrane, seeds: {len(seeds)} on the plane of {len(anchors)} anchors (of {len(points)} support "
                       "points)")
        return seeds, anchors

    def traced_evolve(self, known, seeds, step):
        out = evolve(self, known, seeds, step)
        if tracing[0]:
            log.append(f"    membrane, evolved: {len(out)} points from {len(seeds)} seeds")
        return out

    LozesPDE.seed_hole, LozesPDE.evolve = traced_seed_hole, traced_evolve
    membrane_fill = spatial.membrane_fill

    def traced_membrane_fill(captured, region, *args, **kwargs):
        tracing[0] = region.bounding_radius >= least_radius
        if tracing[0]:
            log.append(f"  membrane of the region at {np.round(region.center, 1).tolist()} "
                       f"r={region.bounding_radius:.1f}: {len(captured)} captured points round it")
        try:
            out = membrane_fill(captured, region, *args, **kwargs)
        finally:
            tracing[0] = False
        if region.bounding_radius >= least_radius:
            # how far the points spread: on voxelized data, the voxels they round to; else their nearest neighbours
            nearest = cKDTree(out).query(out, k=2)[0][:, 1] if len(out) > 1 else np.zeros(0)
            voxels = len(np.unique(np.floor(out + 0.5), axis=0))
            log.append(f"    membrane, returned: {len(out)} points, on {voxels} grid cells of 1 unit, nearest-neighbour "
                       f"distance median {np.median(nearest) if len(nearest) else float('nan'):.3f}")
        return out

    spatial.membrane_fill = traced_membrane_fill


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("damaged", type=Path, help="a `dpcbench damage` output folder (PLY frames + holes.json)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a temporal-fusion parameter (repeatable), e.g. best_surface=false")
    parser.add_argument("--holdouts", action="store_true",
                        help="also each hold-out (closed surface, tube, membrane), with its figures")
    parser.add_argument("--membrane", type=float, default=None, metavar="R",
                        help="also, for each membrane of a region of bounding radius R or more, what each of its tests kept")
    args = parser.parse_args(argv)
    loaded = load_damage_or_exit(args.damaged)
    _, frames, regions = loaded
    log: list = []
    for strategy in spatial.CASCADE:
        strategy.fill = _traced(strategy, log)
    if args.holdouts:
        _traced_holdouts(log)
    if args.membrane is not None:
        _traced_membrane(log, args.membrane)
    out = TemporalFusion(**parse_params(args.param)).inpaint(frames, regions)
    for entry in log:
        if isinstance(entry, str):
            print(entry)
            continue
        centre, radius, name, added, cpu = entry
        print(f"region at {centre} r={radius:.1f}: {name:14s} +{added:6d} points ({cpu:.1f} s CPU)")
    print(f"added {sum(len(o) - len(f) for o, f in zip(out, frames))} points in all")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
