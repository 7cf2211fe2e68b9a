"""The trace scripts under experiments/ that the docs' diagnoses rest on: what they log is what the method decided."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill import membrane, poisson

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


@pytest.fixture
def cascade_trace(monkeypatch):
    """experiments/cascade_trace.py as a module; the fills' hold-outs it wraps are put back after the test."""
    monkeypatch.syspath_prepend(str(EXPERIMENTS))
    for module, name in ((poisson, "_holds_out"), (poisson, "holdout_passes"), (membrane, "holdout_passes")):
        monkeypatch.setattr(module, name, getattr(module, name))
    sys.modules.pop("cascade_trace", None)
    return importlib.import_module("cascade_trace")


def _sphere(n: int = 4000, radius: float = 20.0) -> np.ndarray:
    i = np.arange(n) + 0.5
    polar, azimuth = np.arccos(1.0 - 2.0 * i / n), np.pi * (1.0 + 5.0 ** 0.5) * i
    return radius * np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])


@pytest.mark.parametrize("bound_spacings, decision", [(1.0, "passed"), (1e-3, "refused")])
def test_the_closed_surface_s_hold_out_is_traced_under_its_own_name_with_its_decision(cascade_trace, bound_spacings,
                                                                                        decision):
    """--holdouts logs step 6c's closed-surface test (`poisson._holds_out`), named as such, with the decision the
    test returned: the eighteenth stop's trace logged only the shared rule's calls, so the membrane's passed hold-out
    read as the closed surface's. On a sphere with a cap cut out, the surface without the ring predicts it within one
    spacing (passed) and not within a thousandth of one (refused)."""
    points = _sphere()
    region = HoleRegion("ball", np.array([0.0, 0.0, 20.0]), radius=6.0)
    support = points[~region.contains(points)]
    log: list = []
    cascade_trace._traced_holdouts(log)
    passed = poisson._holds_out(support, region, 2.0, 1.1, 1.1, bound_spacings)
    assert passed == (decision == "passed")
    assert len(log) == 1 and log[0].startswith("  hold-out (closed surface): ") and log[0].endswith(f": {decision}")
    miss = float(log[0].split("miss ")[1].split(",")[0])
    assert 0.0 < miss < 1.1  # the held-out surface lies near the sphere: a smooth cap well within a spacing


def test_fill_audit_by_depth_bins_each_point_by_its_depth_and_gives_the_bin_s_rms(monkeypatch):
    """`fill_audit.depth_lines` (--by-depth): each bin of `DEPTH_EDGES` holds the points whose depth lies in
    [low, high), its off RMS and share over 2 spacings those points' own; empty bins are left out."""
    monkeypatch.syspath_prepend(str(EXPERIMENTS))
    fill_audit = importlib.import_module("fill_audit")
    off = np.array([0.3, 0.4, 1.0, 3.0, 1.0])
    depth = np.array([0.5, 1.99, 2.0, 9.0, 40.0])
    lines = fill_audit.depth_lines(off, depth)
    assert [line.split(":")[0].split()[:2] for line in lines] == [["depth", "0-2"], ["depth", "2-4"], ["depth", "8-16"],
                                                              ["depth", "32-inf"]]
    counts = [int(line.split("points")[1].split()[0]) for line in lines]
    rms = [float(line.split("off RMS")[1].split()[0]) for line in lines]
    assert counts == [2, 1, 1, 1]
    assert rms == pytest.approx([np.sqrt((0.09 + 0.16) / 2), 1.0, 3.0, 1.0], abs=0.005)
    assert lines[2].endswith("(> 2 s: 100%)") and lines[0].endswith("(> 2 s:   0%)")


@pytest.fixture
def membrane_trace(monkeypatch, cascade_trace):
    """experiments/cascade_trace.py with everything `_traced_membrane` wraps put back after the test."""
    from dpcbench.methods.lozes_pde import LozesPDE
    from dpcbench.methods.temporal_fusion import spatial

    for name in ("fit_height_field", "_flat_anchors", "_sheet_bounded", "membrane_sag", "_within_hull_of",
                 "holdout_passes", "grown_agreeing", "between_layers", "far_from"):
        monkeypatch.setattr(membrane, name, getattr(membrane, name))
    monkeypatch.setattr(LozesPDE, "seed_hole", LozesPDE.seed_hole)
    monkeypatch.setattr(LozesPDE, "evolve", LozesPDE.evolve)
    monkeypatch.setattr(spatial, "membrane_fill", spatial.membrane_fill)
    return cascade_trace, spatial


def test_the_membrane_trace_logs_what_each_test_kept_and_ends_on_the_points_the_membrane_returned(membrane_trace):
    """--membrane R logs each membrane of a region of radius R or more, step by step; its counts are the method's.
    A voxelized plane with a disc emptied inside an occlusion box that keeps the rest of the plane in it: the
    membrane spans the disc, a strip of it already covered (as a copy would), and the log's last line counts exactly
    the points `membrane_fill` returned, of more, and then how they spread; a region under R is not logged."""
    from scipy.spatial import cKDTree

    cascade_trace, spatial = membrane_trace
    u, v = np.meshgrid(np.arange(-30.0, 31.0), np.arange(-30.0, 31.0), indexing="ij")
    plane = np.column_stack([u.ravel(), v.ravel(), np.zeros(u.size)])
    captured = plane[np.hypot(plane[:, 0], plane[:, 1]) > 6.0]
    box = HoleRegion.box([0.0, 0.0, 0.0], [12.0, 12.0, 4.0])
    log: list = []
    cascade_trace._traced_membrane(log, 10.0)
    strip = plane[(np.hypot(plane[:, 0], plane[:, 1]) <= 6.0) & (plane[:, 0] >= 3.0)]
    points = spatial.membrane_fill(captured, box, cKDTree(np.vstack([captured, strip])), 1.0, step=1.0)
    assert len(points) > 40  # the disc of radius 6 holds about 113 voxels; the membrane spans most of what is open
    assert log[0].startswith("  membrane of the region at [0.0, 0.0, 0.0] r=") and f"{len(captured)} captured" in log[0]
    assert any(line.startswith("    membrane, seeds: ") for line in log)
    assert any(line == "    membrane, hold-out: passed" or line.startswith("    membrane, hold-out: passed (")
               for line in log)
    kept, total = log[-2].split(": ")[1].split(" of ")
    assert log[-2].startswith("    membrane, not covered already: ") and int(kept) == len(points) < int(total)
    # across a small disc the membrane keeps its seeds' grid: its points round to distinct voxels, about one apart
    cells = len(np.unique(np.floor(points + 0.5), axis=0))
    median = np.median(cKDTree(points).query(points, k=2)[0][:, 1])
    assert log[-1] == (f"    membrane, returned: {len(points)} points, on {cells} grid cells of 1 unit, "
                       f"nearest-neighbour distance median {median:.3f}")
    assert cells >= 0.9 * len(points) and 0.7 < median <= 1.0
    before = len(log)
    spatial.membrane_fill(captured, HoleRegion.box([0.0, 0.0, 0.0], [5.0, 5.0, 4.0]), None, 1.0, step=1.0)
    assert len(log) == before


def test_fill_audit_depth_limit_refuses_only_spatial_points_deeper_than_each_limit(monkeypatch):
    """`fill_audit.depth_limit_lines` (--depth-limit): at each limit L the refusable points kept are those at depth <= L
    (a naive count), the others are always kept, and the scores are those of that result: with every deep spatial
    point taken out, D1 falls as far as leaving them out by hand does; with none spatial, every limit scores alike."""
    monkeypatch.syspath_prepend(str(EXPERIMENTS))
    fill_audit = importlib.import_module("fill_audit")
    from dpcbench.metrics import resolve_peak
    from dpcbench.metrics.pairs import CloudPair

    u, v = np.meshgrid(np.arange(-20.0, 21.0), np.arange(-20.0, 21.0), indexing="ij")
    truth = np.column_stack([u.ravel(), v.ravel(), np.zeros(u.size)])
    radius = np.hypot(truth[:, 0], truth[:, 1])
    damaged, new = truth[radius > 10.0], truth[radius <= 10.0] + [0.0, 0.0, 0.3]  # the fill, 0.3 off the plane
    depth = 10.0 - radius[radius <= 10.0]  # about each point's distance to the damaged frame
    spatial_points = new[:, 0] > 0.0
    empty = CloudPair(truth, damaged, None)
    peak = resolve_peak("intrinsic", CloudPair(truth, np.vstack([damaged, new]), None))
    lines = fill_audit.depth_limit_lines(truth, None, damaged, new, spatial_points, depth, peak, empty)
    assert len(lines) == 1 + len(fill_audit.DEPTH_LIMITS)
    for limit, line in zip(fill_audit.DEPTH_LIMITS, lines[1:]):
        assert int(line.split(":")[1].split()[0]) == int((spatial_points & (depth <= limit)).sum())
        keep = ~spatial_points | (depth <= limit)
        d1, d2 = fill_audit.frame_psnr(CloudPair(truth, np.vstack([damaged, new[keep]]), None), peak)
        assert line.endswith(f"D1 {d1:6.2f} D2 {d2:6.2f}")
    scores = {line.split("points")[1] for line in fill_audit.depth_limit_lines(
        truth, None, damaged, new, np.zeros(len(new), dtype=bool), depth, peak, empty)[1:]}
    assert len(scores) == 1
    first, last = (line.split("D1")[1] for line in (lines[1], lines[-1]))
    assert first != last  # refusing the deep half of the disc changes the score


def test_fill_audit_thin_keeps_one_refusable_point_a_cell_and_every_other_point(monkeypatch):
    """`fill_audit.thinned_lines` (--thin): a fill laid twice, each point with a twin a tenth of a cell away, is
    thinned to one point a cell (a naive count of the occupied cells); the points of other stages are kept even
    where they share a cell; and a fill already one point a cell scores as the fill itself."""
    monkeypatch.syspath_prepend(str(EXPERIMENTS))
    fill_audit = importlib.import_module("fill_audit")
    from dpcbench.metrics import resolve_peak
    from dpcbench.metrics.pairs import CloudPair

    u, v = np.meshgrid(np.arange(-20.0, 21.0), np.arange(-20.0, 21.0), indexing="ij")
    truth = np.column_stack([u.ravel(), v.ravel(), np.zeros(u.size)]) + 0.5
    inside = np.hypot(truth[:, 0] - 0.5, truth[:, 1] - 0.5) <= 8.0
    damaged, fill = truth[~inside], truth[inside] + [0.0, 0.0, 0.2]
    peak = resolve_peak("intrinsic", CloudPair(truth, truth, None))
    once = fill_audit.thinned_lines(truth, None, damaged, fill, np.ones(len(fill), dtype=bool), 1.0, peak)[0]
    d1, d2 = fill_audit.frame_psnr(CloudPair(truth, np.vstack([damaged, fill]), None), peak)
    assert once.endswith(f"D1 {d1:6.2f} D2 {d2:6.2f}") and f": {len(fill)} of {len(fill)} " in once
    twice = np.vstack([fill, fill + [0.1, 0.0, 0.0]])
    spatial_points = np.ones(len(twice), dtype=bool)
    spatial_points[: len(fill) // 2] = False  # a quarter of the points from another stage: all kept
    line = fill_audit.thinned_lines(truth, None, damaged, twice, spatial_points, 1.0, peak)[0]
    cells = len(np.unique(np.floor(twice[spatial_points]), axis=0))
    assert f": {cells} of {int(spatial_points.sum())} " in line and cells < spatial_points.sum()
    seen, keep = set(), ~spatial_points
    for row in np.flatnonzero(spatial_points):  # naive: the first refusable point met in each cell
        cell = tuple(np.floor(twice[row]).astype(int))
        keep[row] = cell not in seen
        seen.add(cell)
    d1, d2 = fill_audit.frame_psnr(CloudPair(truth, np.vstack([damaged, twice[keep]]), None), peak)
    assert line.endswith(f"D1 {d1:6.2f} D2 {d2:6.2f}")
