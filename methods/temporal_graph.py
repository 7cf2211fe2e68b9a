"""The paper's temporal graph inpainting (`temporal-graph`) and its per-frame parent (`fu-nonlocal`).

Fu, Hu, Guo, "3D Dynamic Point Cloud Inpainting via Temporal Consistency on Graphs" (ICME 2020),
Sec. 3, built on Hu, Fu, Guo [Fu18TIP] (non-local self-similarity on graphs). One implementation:
`FuNonlocal` is `TemporalGraph` with the temporal terms switched off (beta = 0, no inter-source
cubes), so the two differ only by the temporal terms (tested: beta = 0 gives identical output).

Variants. ``variant="tuned"`` (the default) is ours; ``variant="paper"`` is the paper configuration
(every step as the paper writes it, every addition of ours off, each paper-silent choice resolved by
the paper's evidence: docs/paper-reading.md); ``variant="literal"`` is the earlier reading of the
paper (known points free, no quantization), kept so that its measurements stay reproducible. The pipeline below is the tuned
variant; each addition of ours names in [brackets] the switch that turns it off. The
`TemporalGraph` docstring lists every switch, the paper configuration step by step with the
paper's lines, each "paper silent" choice, and the precedence (explicit keyword > variant).

Units. Every length parameter is given in *units* u of the data's point spacing (``spacing``; by
default median 8th-NN distance / sqrt(2) of the largest frame, exactly 1 on a voxelized surface).
So the paper's 10-bit values (M = 20 voxels, sigma = 1 voxel) carry over to any bit depth or to
unvoxelized captures with the same number of points across a cube.

Pipeline for frame f. Frames are processed in order; the neighbour f-1 is the already inpainted
output and f+1 the damaged input (the paper's commented text: results feed later frames).

1. Cells of side s = M/4 on a grid; a cube is a 4x4x4 block of cells (side M, step M/4), so every
   point lies in 64 cubes. Per-cube sums come from per-cell sums by summed-volume tables.
2. Missing data: cells that touch a hole region are *pending*: the given regions, or in blind mode
   (regions=None) those of `holes.detection.detect_holes` per frame.
3. Target cubes and holes larger than a cube, from the boundary inward: per group of nearby holes,
   repeatedly take, among the cubes not yet tried with >= ``min_known_points`` known points and a
   pending cell in their central 2x2x2 cells [rim_centred] (a cube centred on the rim: half known
   for the matching, half missing), the one with the most known points (filled points count as known);
   fill it and mark its pending cells done. When no such cube is left, any cube with a pending
   cell may be taken; the group ends when none is left. A cube whose points do not reach its
   pending cells is put off until fills come near [defer_unreachable].
4. Intra-source cube: cubes of the frame that touch no hole [hole_free_candidates] and hold at least as many points as the
   target's known part, ranked by the Euclidean distance between the 4-vectors
   (DC, agtv_weight * AGTV), DC = mean normal, AGTV = mean per-point anisotropic graph total
   variation a_i = sum_{j in 8-NN(i)} exp(-||p_i - p_j||^2 / 2 sigma^2) ||n_i - s_ij n_j||_1
   (s_ij = sign(n_i . n_j), so an unoriented normal flip is no variation). Normals and a_i are
   computed once per frame on a fixed ``feature_fraction`` sample [feature_fraction=1] of the points (candidate
   averages over ~100+ points per cube do not need every point; 4x less work). The best
   ``intra_candidates`` [intra_candidates=1] are aligned (step 5) and the one with the smallest trimmed mean residual
   to the target's known points wins (1 = the paper: the most similar by DC/AGTV alone).
5. Structure matching: the candidate's points (cube grown by one cell [grow_source], so that it still covers the
   target after a rotation) are translated to the target cube and aligned by trimmed point-to-point
   ICP (closed-form Kabsch on pairs from the target's known points to the source: the partial
   side pairs into the complete one; `methods._registration`).
6. Inter-source cubes (temporal only), in f-1 and f+1: the box of side H = 2.5 M centred on the
   co-located cube; each known point of the target votes for its nearest neighbour in that frame
   when it lies in the box; a window of side M slides with stride 1 u over the box and the window
   holding most votes wins (a summed-volume table over a 1 u histogram: O(H^3), not O(H^3 M^3)).
   Its points (grown by one cell) are aligned onto the target's known points as in step 5. An
   inter-source cube of captured data that fits the target better than the intra-source cube
   provides the new points instead [temporal_source].
7. Rows of c_r: the target's m known points, then the *new points*: the aligned intra-source
   points inside the target cube, inside a hole region and in a pending cell [new_points]. Spatial
   graph: K-NN (K = round(sqrt(m))) on the initial estimate Omega_bar c_t + Omega c_s_hat [graph_on], weights
   exp(-d^2 / 2 sigma^2), symmetrised. Temporal links: each row to its nearest neighbour in each
   aligned inter-source cube, weight 1, unless farther than ``link_radius`` point spacings [link_cutoff]
   (the larger of u and the median point spacing) or unless the row
   falls into a hole region of the (not yet inpainted) frame f+1 (a counterpart there would be
   the hole's rim, not the surface) [skip_hole_links].
8. Solve Eq. (6) as one sparse SPD system for the three coordinates (`methods._graph.solve_cube`,
   scipy's sparse LU), with per-row link counts in place of 2I: a first/last frame has one
   neighbour and so uses beta once; a one-frame sequence has none (spatial terms only, with a
   warning). known_points="fixed" keeps the known rows at c_t and solves the new rows only;
   "free" solves the known rows too (the literal variant's reading of "replace the target cube
   with the resulting cube").
9. drop_contradicted [drop_contradicted]: a new point that an inter-source cube contradicts and none supports is
   dropped. Contradicted: no counterpart within ``link_radius`` although that frame has data there,
   and the point lies off that frame's surface (farther than ``off_surface`` link radii from the
   plane of its 8 nearest points there): a gap in a neighbour, e.g. in an inpainted f-1's own
   fill, is no evidence against a point on the surface continued.
10. Voxelized input (integer coordinates about one voxel apart, `metrics.neighbours.is_voxelization`) [snap]: the
   new points are turned into the grid voxels of the surface they sample (`voxelize_fill`: voxels within half a
   voxel of the local tangent plane), minus voxels already occupied.

Colour (``inpaint_with_colours``, fill "auto"; the paper's future work, "attribute inpainting"): colour is a
further signal on each target cube's graph (`cube_colours`). The same Eq. (5)-(6) system as the positions (the
same rows, Omega, spatial Laplacian L, temporal links D_g and weights alpha, gamma, beta) is solved per colour
channel, with c_t the known rows' colours and W_g c_g the colour of each row's counterpart in the inter-source
cube of f-1 (its output colours) and f+1 (its input colours). c_s_hat: where the new rows come from an
inter-source cube (the same surface in a neighbouring frame), their colours there; where they come from an
intra-source cube (a patch elsewhere that matches the target's geometry, not its colour) only a weak anchor to the
nearest known colour, so that the colour is the harmonic extension of the known colours on the cube's graph (the
discrete Laplace equation of Lozes et al.'s colour PDE, on the paper's graph) pulled, in temporal-graph, towards
the colours the same surface has in the neighbouring frames. Known points always keep their colour (Dirichlet
rows, also where known_points="free" moves them: a captured colour is data). A voxel of step 10 takes the colour
of its nearest new point (whose tangent plane chose it). Measured: with the intra-source cube's own colours as
c_s_hat, hole-region colour fell far below the harmonic fill on a real capture (docs/colour.md). The geometry
does not depend on colour.

Code. Each step is a function or a small class: `normal_features` and `CandidateCubes` (step 4's
features), `methods._cubes` (`hole_cells`, `region_groups`, `TargetCubeOrder`: steps 1-3),
`intra_source`, `inter_source_window` / `inter_source` (steps 4 and 6),
`methods._registration.align_best` (step 5), `select_new_points` (step 7's new rows),
`methods._graph.spatial_laplacian` / `temporal_links` (step 7), `methods._graph.solve_cube` (step 8),
`drop_contradicted_rows` (step 9), `voxelize_fill` / `finish_frame` (step 10). The state they pass is
frozen dataclasses: `FrameContext` (one frame), `LocalPoints` (one group of holes, as it fills),
`NeighbourFrame`, `InterSource`, `CubeFill`, `GroupFill`. `_CubeGraphInpainting` only wires them:
`_inpaint_sequence` (frames in order), `_inpaint_frame`, `_fill_group`, `_fill_cube`.

Measured figures behind the choices: docs/notes-journal.md.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import check_regions_near, union_mask
from dpcbench.methods._cubes import (
    CellGrid,
    TargetCubeOrder,
    best_window,
    hole_cells,
    in_box,
    region_groups,
)
from dpcbench.methods._graph import TemporalLinks, solve_cube, spatial_laplacian, temporal_links
from dpcbench.methods._registration import RigidFit, align_best
from dpcbench.methods.base import InpaintingMethod, Regions
from dpcbench.methods.progress import frame_done
from dpcbench.metrics.errors import UserError
from dpcbench.metrics.neighbours import estimate_normals, is_voxelization, point_spacing

if TYPE_CHECKING:
    from dpcbench.holes.regions import HoleRegion

_KNOWN_MODES = ("fixed", "free")
_NEW_POINT_MODES = ("pending-cells", "empty-slots")
_GRAPH_MODES = ("estimate", "source")

#: The values that each variant gives to the switches (parameters left at None). "tuned" is ours
#: (the defaults); "paper" follows the paper step by step, every addition of ours off (see the
#: `TemporalGraph` docstring, "The paper configuration", for each switch and the paper's text).
VARIANTS: dict[str, dict[str, Any]] = {
    "tuned": dict(intra_candidates=4, temporal_source=True, drop_contradicted=True, known_points="fixed",
                  link_cutoff=True, skip_hole_links=True, rim_centred=True, defer_unreachable=True,
                  hole_free_candidates=True, grow_source=True, new_points="pending-cells", snap="auto",
                  graph_on="estimate", feature_fraction=0.25),
    "paper": dict(intra_candidates=1, temporal_source=False, drop_contradicted=False, known_points="fixed",
                  link_cutoff=False, skip_hole_links=False, rim_centred=False, defer_unreachable=False,
                  hole_free_candidates=False, grow_source=False, new_points="pending-cells", snap="auto",
                  graph_on="source", feature_fraction=1.0),
}
#: issue 11's reading of the paper, kept so that its measurements stay reproducible: the paper
#: configuration with known points free ("replace the target cube with the resulting cube" read
#: as moving the known rows too) and no quantization of the output (docs/paper-reading.md).
VARIANTS["literal"] = dict(VARIANTS["paper"], known_points="free", snap=False)


# -- state ------------------------------------------------------------------------------------------
# Small frozen records passed between the steps. Arrays inside them are never written after
# construction; a step that changes the state returns a new record.


@dataclass(frozen=True)
class NeighbourFrame:
    """A neighbouring frame g of the frame f being inpainted (g = f - 1 or f + 1).

    points (N_g, 3): f-1's inpainted output, or f+1's damaged input. tree: cKDTree on ``points``.
    regions: hole regions of g whose points are still missing (those of f+1; none for the
    inpainted f-1): a row that maps into one has no counterpart in g. source_regions: the hole
    regions of g's input (f-1's too): near one, g's points are not captured data. colours (N_g, 3)
    float64: their RGB (f-1's output colours, f+1's input colours) when the run carries colour, else None.
    """

    points: np.ndarray
    tree: cKDTree
    regions: Sequence[HoleRegion]
    source_regions: Sequence[HoleRegion]
    colours: np.ndarray | None = None


@dataclass(frozen=True)
class CandidateCubes:
    """The intra-source candidates of one frame: C cubes with their DC / AGTV features.

    lower (C, 3): lower corner of each cube (side M). count (C,): points in it (float). dc (C, 3):
    mean unit normal of its sampled points. agtv (C,): mean per-point AGTV of its sampled points.
    tree: cKDTree on the 4-vectors (dc, agtv_weight * agtv), None when C = 0.
    """

    lower: np.ndarray
    count: np.ndarray
    dc: np.ndarray
    agtv: np.ndarray
    tree: cKDTree | None

    @classmethod
    def build(cls, grid: CellGrid, points: np.ndarray, normals: np.ndarray, agtv: np.ndarray,
              regions: Sequence[HoleRegion], *, min_known_points: int, hole_free: bool,
              agtv_weight: float) -> CandidateCubes:
        """Every cube of ``grid`` with >= ``min_known_points`` points and at least one point that has
        features (``agtv`` not NaN: the `normal_features` sample), and with ``hole_free`` no cell
        touching a hole region. dc = sum of the sampled normals / number sampled, the same for agtv.
        Per-cube sums come from per-cell sums (`CellGrid.cube_sums`): O(cells), whatever M is."""
        cube_counts = grid.cube_sums(grid.bin(points))
        ok = cube_counts >= min_known_points
        if hole_free:
            ok &= grid.cube_sums(hole_cells(grid, regions).astype(np.int64)) == 0
        sampled = ~np.isnan(agtv)
        sample_counts = grid.cube_sums(grid.bin(points[sampled]))
        ok &= sample_counts > 0
        anchors = np.argwhere(ok)
        count = cube_counts[ok].astype(np.float64)
        samples = sample_counts[ok].astype(np.float64)
        dc = grid.cube_sums(grid.bin(points[sampled], normals[sampled]))[ok] / samples[:, None]
        mean_agtv = grid.cube_sums(grid.bin(points[sampled], agtv[sampled]))[ok] / samples
        tree = cKDTree(np.column_stack([dc, agtv_weight * mean_agtv])) if len(anchors) else None
        return cls(grid.cube_lower(anchors), count, dc, mean_agtv, tree)

    def ranked(self, query: np.ndarray, m: int, target_lower: np.ndarray, *, cube: float, cell: float,
               cells_per_cube: int, hole_free: bool, agtv_weight: float, want: int) -> np.ndarray:
        """Indices (<= want,) of the candidates most similar to the target, best first.

        query (4,): the target's (DC, agtv_weight * AGTV). Similarity: Euclidean distance between the
        4-vectors (paper silent; [Fu18TIP] gives no formula). A candidate must hold >= m points (the
        target's known part: it must cover it to supply the missing one), and unless ``hole_free``
        must not overlap the target cube at ``target_lower`` (it shares the target's hole, and the
        target is trivially the most similar to itself). The nearest 64 (+ the (2 c - 1)^3
        overlapping cubes) come from the k-d tree; when fewer than ``want`` of them are usable,
        all usable candidates are ranked by brute force (stable order)."""
        if self.tree is None:
            return np.empty(0, dtype=np.int64)

        def usable(index: np.ndarray | slice) -> np.ndarray:
            # tested on the k nearest only: on a whole frame C is 10^5 cubes, k a few hundred
            ok = self.count[index] >= m
            if not hole_free:
                ok &= (np.abs(self.lower[index] - target_lower) >= cube - 0.5 * cell).any(axis=1)
            return ok

        k = min(len(self.count), 64 if hole_free else 64 + (2 * cells_per_cube - 1) ** 3)
        _, order = self.tree.query(query, k=k)
        order = np.atleast_1d(order)
        order = order[usable(order)]
        if len(order) < want:
            # rare: few big-enough cubes among the nearest features; rank all of them
            big = np.flatnonzero(usable(slice(None)))
            if not len(big):
                return big
            feats = np.column_stack([self.dc[big], agtv_weight * self.agtv[big]])
            order = big[np.argsort(np.linalg.norm(feats - query, axis=1), kind="stable")]
        return order[:want]


@dataclass(frozen=True)
class FrameContext:
    """What every target cube of one frame reads (the frame's "context").

    points (N, 3), tree: the damaged frame and its cKDTree. grid: its cells (side M / c, c = cells_per_cube,
    padded by c cells). cube: M in coordinates (cube_size * unit); cell: M / c; unit: u; sigma: the
    graph's Gaussian width in coordinates (sigma * u). candidates: its intra-source candidates.
    neighbours: the neighbouring frames (none without temporal terms). link: the longest temporal
    link (None without temporal terms). slot: side of a slot for new_points="empty-slots" (else None).
    colours (N, 3) float64: the frame's RGB when the run carries colour (`cube_colours`), else None.
    """

    points: np.ndarray
    tree: cKDTree
    grid: CellGrid
    cube: float
    cell: float
    unit: float
    sigma: float
    candidates: CandidateCubes
    neighbours: tuple[NeighbourFrame, ...]
    link: float | None
    slot: float | None
    colours: np.ndarray | None = None


@dataclass(frozen=True)
class CubeFill:
    """What one target cube contributes. new (P, 3): its new points (after drop_contradicted).
    moved_rows (m,) and moved (m, 3): with known_points="free", the rows of `LocalPoints` that
    the solve moved and where to; None with "fixed" or when nothing was solved. colours (P, 3): the new
    points' colours (`cube_colours`), None when the run carries no colour."""

    new: np.ndarray
    moved_rows: np.ndarray | None = None
    moved: np.ndarray | None = None
    colours: np.ndarray | None = None


@dataclass(frozen=True)
class LocalPoints:
    """The points near one group of holes, as the group's fills go on (the group's "local" state).

    points (L, 3): the frame's points in the group's box, then the points filled so far. normals
    (L, 3), agtv (L,): their features (NaN off the sample and for filled points). index (L,): row in
    the frame, -1 for a filled point. Filled points count as known for the later target cubes.
    colours (L, 3): their RGB (the frame's, then the fills'), None when the run carries no colour.
    """

    points: np.ndarray
    normals: np.ndarray
    agtv: np.ndarray
    index: np.ndarray
    colours: np.ndarray | None = None

    def apply(self, fill: CubeFill) -> LocalPoints:
        """The state after ``fill``: its moved rows at their new positions (their colours kept), its new
        points (and their colours) appended."""
        points = self.points
        if fill.moved_rows is not None:
            points = points.copy()
            points[fill.moved_rows] = fill.moved
        if not len(fill.new):
            return replace(self, points=points)
        nan = np.full((len(fill.new), 3), np.nan)
        colours = None
        if self.colours is not None:
            colours = np.vstack([self.colours, nan if fill.colours is None else fill.colours])
        return LocalPoints(np.vstack([points, fill.new]), np.vstack([self.normals, nan]),
                           np.concatenate([self.agtv, nan[:, 0]]),
                           np.concatenate([self.index, np.full(len(fill.new), -1)]), colours)


@dataclass(frozen=True)
class GroupFill:
    """What one group of holes contributes: moved_index (K,) rows of the frame moved to
    moved_points (K, 3) (known_points="free" only), and the new points (P, 3) with their colours (P, 3; None
    when the run carries no colour)."""

    moved_index: np.ndarray
    moved_points: np.ndarray
    new: np.ndarray
    colours: np.ndarray | None = None


@dataclass(frozen=True)
class InterSource:
    """An inter-source cube of a neighbouring frame aligned onto a target cube's known points.

    aligned (S, 3) = source @ rotation.T + translation. residual: trimmed mean distance of the
    target's known points to ``aligned`` (`alignment_residual`). raw: no hole region of that
    frame's input lies within one cube of the target, so its points there are captured data.
    regions: that frame's hole regions still missing (`NeighbourFrame.regions`). colours (S, 3): the
    source points' colours in that frame (None when the run carries no colour).
    """

    aligned: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    residual: float
    raw: bool
    regions: Sequence[HoleRegion]
    colours: np.ndarray | None = None


# -- steps --------------------------------------------------------------------------------------------
# The pipeline of one frame, in order: features and candidates (`normal_features`,
# `CandidateCubes`), the cubes (`methods._cubes`: `hole_cells`, `region_groups`,
# `TargetCubeOrder`), the sources (`intra_source`, `inter_source_window`, `inter_source`), their
# alignment (`methods._registration.align_best`), the new points (`select_new_points`), the graph
# (`methods._graph.spatial_laplacian`, `temporal_links`), the solve (`methods._graph.solve_cube`),
# and the post-processing (`drop_contradicted_rows`, `voxelize_fill`, `finish_frame`).


def cube_unit(frame: np.ndarray, tree: cKDTree | None, spacing: float | str | None, voxel_data: bool,
              name: str) -> float:
    """The unit u (coordinates) of every length parameter, from the largest ``frame`` (N, 3).

    spacing="points": the median point spacing (`metrics.neighbours.point_spacing`); a number: that
    number; None: 1 on voxelized data (``voxel_data``: `metrics.neighbours.is_voxelization`), else 1/1024 of the
    largest bounding-box side (the paper sets M "according to the coordinate range of P_f": M = 20 on a body 1023
    units tall).
    """
    if spacing == "points":
        return point_spacing(frame, tree=tree)
    if spacing is not None:
        return float(spacing)
    if voxel_data:
        return 1.0  # one voxel, whatever the bit depth
    extent = float(np.ptp(frame, axis=0).max())
    if not extent > 0:
        raise UserError(f"{name}: the frames have zero extent; pass spacing=<length of one unit>")
    return extent / 1024.0


def normal_features(points: np.ndarray, tree: cKDTree, sigma: float, feature_fraction: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (N, 3) and per-point AGTV a_i (N,) on a fixed sample of the points, NaN elsewhere.

    The sample is a fixed-seed ``feature_fraction`` of the points (all of them at 1.0). Normal of a
    sampled point: the eigenvector of the smallest eigenvalue of the covariance of its 10 nearest
    points in the whole frame, oriented away from the frame centroid (`metrics.neighbours.estimate_normals`
    at the sampled positions, reusing ``tree``, the k-d tree of ``points``). AGTV of a sampled point:
    a_i = sum_{j in 8-NN of i in the sample} exp(-||p_i - p_j||^2 / 2 sigma_s^2) ||n_i - s_ij n_j||_1,
    s_ij = sign(n_i . n_j), sigma_s = sigma / sqrt(feature_fraction) (the sample's spacing grows
    as 1 / sqrt(fraction) on a surface).
    """
    n = len(points)
    count = max(min(n, 9), int(round(feature_fraction * n)))
    sample = np.sort(np.random.default_rng(0).choice(n, count, replace=False)) if count < n else np.arange(n)
    sampled = points[sample]
    sample_normals = estimate_normals(points, 10, queries=sampled, tree=tree, orient_from=points.mean(axis=0))
    k = min(9, count)
    # the whole frame sampled (feature_fraction 1, the paper's): the frame's own tree is a tree of the same rows
    # in the same order, so it answers the same query with the same neighbours; no second tree of N points
    sample_tree = tree if count == n and tree.n == n else cKDTree(sampled)
    dist, nbr = sample_tree.query(sampled, k=k, workers=-1)
    dist, nbr = dist[:, 1:], nbr[:, 1:]
    neighbour_normals = sample_normals[nbr]
    sign = np.sign(np.einsum("ij,ikj->ik", sample_normals, neighbour_normals))
    sign[sign == 0] = 1.0
    diff = np.abs(sample_normals[:, None, :] - sign[..., None] * neighbour_normals).sum(axis=2)
    sigma_s = sigma / np.sqrt(min(1.0, count / n))
    sample_agtv = (np.exp(-dist ** 2 / (2.0 * sigma_s ** 2)) * diff).sum(axis=1)
    normals = np.full((n, 3), np.nan)
    agtv = np.full(n, np.nan)
    normals[sample] = sample_normals
    agtv[sample] = sample_agtv
    return normals, agtv


def intra_source(target: np.ndarray, lower: np.ndarray, query: np.ndarray, ctx: FrameContext, *,
                 intra_candidates: int, hole_free: bool, grow_source: bool, cells_per_cube: int,
                 agtv_weight: float, icp_iterations: int, residual: bool) -> RigidFit | None:
    """The aligned intra-source cube of the target cube at ``lower``, or None.

    target (m, 3): the target's known points; query (4,): its (DC, agtv_weight * AGTV). The best
    ``intra_candidates`` of `CandidateCubes.ranked` (the paper: 1) give source patches: a
    candidate's points within its cube, grown by one cell with ``grow_source`` (so that it still
    covers the target after a rotation), translated by ``lower - candidate lower``. `align_best`
    aligns them onto ``target`` (several: screened by the smallest alignment residual).
    """
    cand = ctx.candidates
    choices = cand.ranked(query, len(target), lower, cube=ctx.cube, cell=ctx.cell, cells_per_cube=cells_per_cube,
                          hole_free=hole_free, agtv_weight=agtv_weight, want=intra_candidates)
    if not len(choices):
        return None
    half = ctx.cube / 2.0
    grow = ctx.cell if grow_source else 0.0
    sources: list[np.ndarray | None] = []
    for index in choices:
        source_lower = cand.lower[index]
        source_idx = ctx.tree.query_ball_point(source_lower + half, half + grow, p=np.inf)
        sources.append(ctx.points[source_idx] + (lower - source_lower) if len(source_idx) >= 3 else None)
    return align_best(sources, target, iterations=icp_iterations, residual=residual, unit=ctx.unit)


def inter_source_window(target: np.ndarray, lower: np.ndarray, neighbour: NeighbourFrame, *, cube: float,
                        search_box: float, unit: float) -> np.ndarray | None:
    """Lower corner (3,) of the inter-source cube of ``neighbour`` for the target cube at ``lower``.

    The search box of side H = search_box * M is centred on the co-located cube. Each known target
    point (m, 3) votes for its nearest neighbour in the frame when that lies in the box; the window
    of side M (stride one unit) holding most votes wins (`methods._cubes.best_window`, ties to
    the centre). None when fewer than 3 votes fall in the box.
    """
    box = search_box * cube
    box_lower = lower + cube / 2.0 - box / 2.0
    # a point whose nearest neighbour is outside the box has no counterpart in the box near it
    _, nearest = neighbour.tree.query(target)
    votes = neighbour.points[nearest]
    votes = votes[in_box(votes, box_lower, box)]
    if len(votes) < 3:
        return None
    window_lower, _ = best_window(votes, box_lower, box, cube, unit)
    return window_lower


def inter_source(target: np.ndarray, lower: np.ndarray, neighbour: NeighbourFrame, *, cube: float, cell: float,
                 unit: float, search_box: float, grow_source: bool, icp_iterations: int) -> InterSource | None:
    """The aligned inter-source cube of one neighbouring frame for the target cube at ``lower``
    (`inter_source_window`, its points grown by one cell with ``grow_source``, aligned onto the
    target's known points (m, 3) by ``icp_iterations`` of ICP), or None when the frame has fewer
    than 3 points there."""
    window_lower = inter_source_window(target, lower, neighbour, cube=cube, search_box=search_box, unit=unit)
    if window_lower is None:
        return None
    half = cube / 2.0
    window_idx = neighbour.tree.query_ball_point(window_lower + half, half + (cell if grow_source else 0.0),
                                                 p=np.inf)
    if len(window_idx) < 3:
        return None
    fit = align_best([neighbour.points[window_idx]], target, iterations=icp_iterations, unit=unit)
    if fit is None:
        return None
    # raw: an inpainted f-1 would otherwise hand its own fill on, and a fill copied from frame to
    # frame shrinks and drifts with the hole
    centre = lower + cube / 2.0
    raw = all(np.linalg.norm(r.center - centre) > r.bounding_radius + cube for r in neighbour.source_regions)
    colours = None if neighbour.colours is None else neighbour.colours[window_idx]
    return InterSource(fit.aligned, fit.rotation, fit.translation, fit.residual, raw, neighbour.regions, colours)


def select_new_points(source: np.ndarray, target: np.ndarray, lower: np.ndarray, regions: Sequence[HoleRegion],
                      pending: np.ndarray, source_cells: np.ndarray, *, cube: float, mode: str,
                      slot: float | None) -> np.ndarray:
    """The new points (P, 3): the aligned source points (S, 3) that fill the target cube's missing part.

    Always inside the target cube (side ``cube`` at ``lower``) and inside a hole region.
    mode "pending-cells": also in a pending cell (``source_cells`` (S, 3): their cells in the local
    window of ``pending``; a cell outside the window is not pending). mode "empty-slots": also in a
    slot (voxel of side ``slot``, by rounding) that holds no ``target`` point (m, 3) yet; one point
    per slot, the first in source order.
    """
    in_window = ((source_cells >= 0) & (source_cells < pending.shape)).all(axis=1)
    in_pending = np.zeros(len(source), dtype=bool)
    in_pending[in_window] = pending[tuple(source_cells[in_window].T)]
    inside = np.zeros(len(source), dtype=bool)
    for region in regions:
        inside |= region.contains(source)
    inside &= in_box(source, lower, cube)
    if mode == "pending-cells":
        return source[in_pending & inside]
    # "empty-slots" (the other reading of Omega, the missing slots of the M^3 grid): a source point
    # in a hole region whose slot holds no point of the frame yet, captured or filled earlier
    new = source[inside]
    if len(new):
        if slot is None:
            raise ValueError("new_points='empty-slots' needs the side of a slot")
        slots = np.floor(new / slot + 0.5).astype(np.int64)
        taken = {tuple(key) for key in np.floor(target / slot + 0.5).astype(np.int64)}
        _, first = np.unique(slots, axis=0, return_index=True)
        new = new[[i for i in np.sort(first) if tuple(slots[i]) not in taken]].reshape(-1, 3)
    return new


def drop_contradicted_rows(new: np.ndarray, links: Sequence[TemporalLinks], m: int) -> np.ndarray:
    """The solved new rows (P, 3) (rows m.. of the cube) that no neighbour contradicts or that one
    supports: kept where any(supported) or not any(contradicted) over the ``links``."""
    return new[uncontradicted(links, m)]


def uncontradicted(links: Sequence[TemporalLinks], m: int) -> np.ndarray:
    """Mask (P,) of the new rows (rows m.. of the cube) `drop_contradicted_rows` keeps."""
    supported = np.any([link.supported[m:] for link in links], axis=0)
    against = np.any([link.contradicted[m:] for link in links], axis=0)
    return supported | ~against


#: weight of the colour data term of a new row whose source is an intra-source cube (a patch elsewhere in the frame
#: that matches the target's geometry, not its colour), relative to alpha: small, so that the row's colour is the
#: graph's harmonic extension of the known colours (and the temporal terms), only anchored (so that the system is
#: never singular) to its nearest known row's colour. With the intra-source cube's own colours as c_s_hat (weight
#: alpha) fu-nonlocal's hole-region cpsnr_y on MVUB ricardo9 fell from 29.82 (harmonic fill) to 15.15 dB
#: (docs/colour.md)
INTRA_COLOUR_WEIGHT = 1e-3


def cube_colours(rows: np.ndarray, m: int, known_colours: np.ndarray, source: np.ndarray,
                 source_colours: np.ndarray | None, inter: Sequence[InterSource], links: Sequence[TemporalLinks],
                 laplacian, *, alpha: float, gamma: float, beta: float) -> np.ndarray:
    """Colours (P, 3) float64 of a cube's new rows: colour as a further signal on the cube's graph (the paper's
    future work), Eq. (5)-(6) solved per colour channel on the same rows, Omega, L and temporal links as the
    positions (`methods._graph.solve_cube`): c_t the m known rows' colours ``known_colours`` (m, 3), kept
    (Dirichlet rows: captured colours are data, whatever the variant does with the known positions); each
    temporal term W_g c_g the colour of the row's nearest point in that inter-source cube (the counterpart its
    position is linked to, with the same link mask). c_s_hat: where the new rows come from an inter-source cube
    (``source_colours`` given: the same surface in a neighbouring frame) each row's colour there, weight alpha;
    from an intra-source cube (``source_colours`` None: a patch elsewhere that matches the geometry, not the
    colour) each row's nearest known row's colour with weight alpha * `INTRA_COLOUR_WEIGHT`, so that the colour is
    the harmonic extension of the known colours on the graph, pulled towards the temporal counterparts."""
    new = rows[m:]
    if source_colours is not None:
        _, nearest = cKDTree(source).query(new)
        prior, weight = source_colours[nearest], alpha
    else:
        _, nearest = cKDTree(rows[:m]).query(new)
        prior, weight = known_colours[nearest], alpha * INTRA_COLOUR_WEIGHT
    signal = np.vstack([known_colours, prior])
    temporal = []
    for cube, link in zip(inter, links):
        if cube.colours is not None:
            _, counterpart = cKDTree(cube.aligned).query(rows)
            temporal.append((cube.colours[counterpart], link.linked))
    known = np.zeros(len(rows), dtype=bool)
    known[:m] = True
    return solve_cube(signal, signal, known, laplacian, alpha=weight, gamma=gamma, beta=beta, temporal=temporal,
                      fix_known=True)[m:]


def voxelize_fill(added: np.ndarray, regions: Sequence[HoleRegion]) -> np.ndarray:
    """The grid voxels (integer points) of the surface that the new points ``added`` (P, 3) sample.

    Rounding each new point on its own leaves gaps and doubles where the filled patch is rotated
    or smoothed off the lattice. Instead every voxel within one step of a new point, inside a
    hole region, is kept when it lies within half a voxel of the local tangent plane of its
    nearest new point (plane from the 8 nearest new points) and within 1.5 voxels of that point
    (so that a one-voxel seam between the fills of two cubes closes).
    """
    if len(added) < 4:
        return np.unique(np.floor(added + 0.5), axis=0)
    tree = cKDTree(added)
    _, nbr = tree.query(added, k=min(8, len(added)))
    neigh = added[nbr] - added[nbr].mean(axis=1, keepdims=True)
    _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", neigh, neigh))
    normals = vectors[:, :, 0]
    offsets = np.stack(np.meshgrid(*[np.arange(-1, 2)] * 3, indexing="ij"), -1).reshape(-1, 3)
    # round half up, not half to even: a lattice shifted by half a voxel must not fold
    base = np.unique(np.floor(added + 0.5), axis=0)
    voxels = np.unique((base[:, None, :] + offsets[None]).reshape(-1, 3), axis=0)
    inside = np.zeros(len(voxels), dtype=bool)
    for region in regions:
        inside |= region.contains(voxels)
    voxels = voxels[inside]
    dist, nearest = tree.query(voxels)
    off_plane = np.abs(np.einsum("ij,ij->i", voxels - added[nearest], normals[nearest]))
    return voxels[(dist <= 1.5) & (off_plane <= 0.5)]


def finish_frame(out: np.ndarray, added: np.ndarray, regions: Sequence[HoleRegion], *, voxelized: bool,
                 round_known: bool) -> np.ndarray:
    """The output frame (N + P', 3): the frame's points ``out`` (N, 3), then the new points
    ``added`` (P, 3). Voxelized input (and new points): the new points become voxels
    (`voxelize_fill`) minus those already occupied (a point within half a voxel), and with
    ``round_known`` (known_points="free") the moved known points are rounded half up."""
    if voxelized and len(added):
        if round_known:
            out = np.floor(out + 0.5)
        added = voxelize_fill(added, regions)
        dist, _ = cKDTree(out).query(added, distance_upper_bound=0.5)
        added = added[~np.isfinite(dist)]
    return np.vstack([out, added])


class _CubeGraphInpainting(InpaintingMethod):
    """Shared machinery; subclasses fix whether the temporal terms are used (``_temporal``)."""

    _temporal: bool = True
    detects_holes = True
    needs_regions = False

    # The parameters, stored by the subclasses' __init__. The switches (VARIANTS) are None there
    # ("the variant's value", so their __init__ parameters carry no type: any value is checked by
    # `_validate` once resolved); the types below are those of the resolved copy (`_configured`),
    # the only object the pipeline runs on.
    variant: str
    cube_size: float
    cells_per_cube: int
    search_box: float
    alpha: float
    beta: float
    gamma: float
    sigma: float
    k_neighbors: int | None
    spacing: float | str | None
    known_points: str
    min_known_points: int
    icp_iterations: int
    link_radius: float
    snap: str | bool
    agtv_weight: float
    intra_candidates: int
    feature_fraction: float
    drop_contradicted: bool
    temporal_source: bool
    off_surface: float | None
    link_cutoff: bool
    skip_hole_links: bool
    rim_centred: bool
    defer_unreachable: bool
    hole_free_candidates: bool
    grow_source: bool
    new_points: str
    graph_on: str

    # -- parameters -------------------------------------------------------------------------
    def _beta(self) -> float:
        return float(self.beta) if self._temporal else 0.0

    # -- variant ----------------------------------------------------------------------------
    def get_params(self) -> dict:
        """The constructor parameters with every switch left at None replaced by the variant's value
        (so a stored record names each switch as it ran). An unknown variant leaves them at None
        (`inpaint` refuses it)."""
        params = super().get_params()
        for name, value in VARIANTS.get(str(params.get("variant")), {}).items():
            if name in params and params[name] is None:
                params[name] = value
        return params

    def _configured(self) -> _CubeGraphInpainting:
        """A copy whose switches hold their resolved values (explicit ones win over the variant's)."""
        if self.variant not in VARIANTS:
            raise ValueError(f"{self.name}: variant must be one of {tuple(VARIANTS)}, got {self.variant!r}")
        run = copy.copy(self)
        run.__dict__.update(self.get_params())
        return run

    def validate_params(self) -> _CubeGraphInpainting:
        """As `InpaintingMethod.validate_params`, on the switches as the variant resolves them (a switch
        left at None takes the variant's value, so None itself is never checked)."""
        try:
            run = self._configured()
        except ValueError as err:  # an unknown variant
            raise UserError(str(err)) from None
        InpaintingMethod.validate_params(run)
        return self

    def _validate(self) -> None:
        def positive(name: str) -> None:
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
                raise ValueError(f"{self.name}: {name} must be a positive number, got {value!r}")

        for name in ("cube_size", "sigma", "link_radius", "search_box"):
            if hasattr(self, name):
                positive(name)
        for name in ("alpha", "gamma", "beta", "agtv_weight"):
            value = getattr(self, name, 0.0)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not value >= 0:
                raise ValueError(f"{self.name}: {name} must be a number >= 0, got {value!r}")
        if not self.alpha > 0:
            raise ValueError(f"{self.name}: alpha must be > 0 (it anchors the new points to the source cube)")
        if not isinstance(self.cells_per_cube, int) or self.cells_per_cube < 1:
            raise ValueError(f"{self.name}: cells_per_cube must be an integer >= 1, got {self.cells_per_cube!r}")
        if not isinstance(self.min_known_points, int) or self.min_known_points < 3:
            raise ValueError(f"{self.name}: min_known_points must be an integer >= 3, got {self.min_known_points!r}")
        if self.k_neighbors is not None:
            if not isinstance(self.k_neighbors, int) or self.k_neighbors < 1:
                raise ValueError(f"{self.name}: k_neighbors must be None (sqrt(m)) or an integer >= 1, "
                                 f"got {self.k_neighbors!r}")
            if self.k_neighbors > self.min_known_points:
                raise ValueError(
                    f"{self.name}: k_neighbors={self.k_neighbors} exceeds min_known_points="
                    f"{self.min_known_points}, so a cube could have fewer points m than K; "
                    "lower k_neighbors or raise min_known_points (K must be <= m)")
        if self.spacing not in (None, "points"):
            positive("spacing")
        if self.known_points not in _KNOWN_MODES:
            raise ValueError(f"{self.name}: known_points must be one of {_KNOWN_MODES}, got {self.known_points!r}")
        if self.snap not in ("auto", True, False):
            raise ValueError(f"{self.name}: snap must be 'auto', true or false, got {self.snap!r}")
        if not isinstance(self.feature_fraction, (int, float)) or not 0 < self.feature_fraction <= 1:
            raise ValueError(f"{self.name}: feature_fraction must be in (0, 1], got {self.feature_fraction!r}")
        if not isinstance(self.intra_candidates, int) or self.intra_candidates < 1:
            raise ValueError(f"{self.name}: intra_candidates must be an integer >= 1, got {self.intra_candidates!r}")
        if self.off_surface is not None and (not isinstance(self.off_surface, (int, float))
                                             or isinstance(self.off_surface, bool) or not self.off_surface >= 0):
            raise ValueError(f"{self.name}: off_surface must be None or a number >= 0, got {self.off_surface!r}")
        if not isinstance(self.icp_iterations, int) or self.icp_iterations < 0:
            raise ValueError(f"{self.name}: icp_iterations must be an integer >= 0, got {self.icp_iterations!r}")
        for name in ("link_cutoff", "skip_hole_links", "rim_centred", "defer_unreachable", "hole_free_candidates",
                     "grow_source", "temporal_source", "drop_contradicted"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{self.name}: {name} must be true or false (or left out: the variant's "
                                 f"value), got {getattr(self, name)!r}")
        if self.new_points not in _NEW_POINT_MODES:
            raise ValueError(f"{self.name}: new_points must be one of {_NEW_POINT_MODES}, got {self.new_points!r}")
        if self.graph_on not in _GRAPH_MODES:
            raise ValueError(f"{self.name}: graph_on must be one of {_GRAPH_MODES}, got {self.graph_on!r}")

    # the voxelization of step 10 under its former name: methods.temporal_fusion calls it
    _voxelize = staticmethod(voxelize_fill)

    # -- sequence ---------------------------------------------------------------------------
    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        """Inpaint the sequence ``frames`` (list of (N_f, 3)) given the hole regions of each frame
        (a list of lists of `holes.regions.HoleRegion`), or blind (None: `holes.detection`).
        Returns a new list of (N'_f, 3) frames: each frame's points (moved with known_points="free"),
        then its new points."""
        checked, regions = self._check_inputs(frames, regions)
        return self._configured()._inpaint_sequence(checked, regions)[0]

    def inpaint_with_colours(self, frames: list[np.ndarray], colours: Sequence[np.ndarray], regions: Regions = None,
                             *, fill: str = "auto") -> tuple[list[np.ndarray], list[np.ndarray]]:
        """``inpaint``'s output with colour solved as a further signal on each target cube's graph (`cube_colours`;
        known points keep their colour) for ``fill`` "auto" or "source" where the graph has temporal terms (beta > 0
        and more than one frame); "nearest" and "harmonic" colour the new points by that fill alone
        (`InpaintingMethod.inpaint_with_colours`), and so does "auto" without temporal terms (fu-nonlocal, one
        frame): an intra-source cube gives no colour (another place of the body), so what the cube's system then
        solves is the harmonic extension of the known colours on the cube's graph, cube by cube, which the generic
        harmonic fill solves over the whole hole at once; measured (docs/colour.md) the cube-by-cube solve was the
        worse of the two in the holes, ricardo9 27.08 against 29.82 dB Y and the bunny 26.42 against 26.84."""
        if fill not in ("auto", "source") or self._configured()._beta() == 0 or len(frames) < 2:
            return super().inpaint_with_colours(frames, colours, regions, fill=fill)
        from dpcbench.methods._colour import colour_frame

        _, checked_colours = self._check_colours(frames, colours, regions, fill)
        checked, regions = self._check_inputs(frames, regions)
        outputs, carried = self._configured()._inpaint_sequence(checked, regions, checked_colours)
        assert carried is not None
        out = []
        for frame, col, points, values in zip(checked, checked_colours, outputs, carried):
            # every row carries its colour (a row the solve left without one, if any, takes the fill's)
            sources = np.full((len(points), 3), -1, dtype=np.int16)
            known = np.isfinite(values).all(axis=1)
            sources[known] = np.clip(np.rint(values[known]), 0, 255).astype(np.int16)
            out.append(colour_frame(frame, col, points, fill, sources))
        return outputs, out

    def _inpaint_sequence(self, frames: list[np.ndarray], regions: list | None,
                          colours: list[np.ndarray] | None = None) -> tuple[list[np.ndarray], list | None]:
        """(outputs, their colours (N'_f, 3) float64 or None): the frames in order (module docstring); colours
        carried when the frames' ``colours`` are given."""
        self._validate()
        trees: dict[int, cKDTree] = {}  # k-d tree of each input frame, built once, dropped once behind

        def tree_of(f: int) -> cKDTree:
            if f not in trees:
                trees[f] = cKDTree(frames[f])
            return trees[f]

        largest = max(range(len(frames)), key=lambda f: len(frames[f]))
        voxel_data = is_voxelization(frames, tree_of(largest))
        voxelized = self.snap is True or (self.snap == "auto" and voxel_data)
        unit = cube_unit(frames[largest], tree_of(largest) if self.spacing == "points" else None, self.spacing,
                         voxel_data, self.name)
        if regions is None:
            from dpcbench.holes.detection import detect_holes  # lazily: blind protocol only

            regions = [list(detect_holes(frame)) for frame in frames]
        for f in range(len(frames)):
            if regions[f]:
                self._check_regions(f, frames[f], regions[f], unit, voxel_data, tree_of(f))
        beta = self._beta()
        link_distance = self._link_distance(frames[largest], tree_of(largest), unit, voxel_data) if beta > 0 else None
        # a slot of the paper's M^3 grid of a cube: one voxel; on unvoxelized data one point spacing
        slot = None
        if self.new_points == "empty-slots":
            slot = unit if voxel_data else max(unit, point_spacing(frames[largest], tree=tree_of(largest)))
        if beta > 0 and len(frames) == 1:
            warnings.warn(f"{self.name}: a one-frame sequence has no neighbouring frames; "
                          "using the spatial terms only (as fu-nonlocal)", stacklevel=2)
        outputs: list[np.ndarray] = []
        out_colours: list[np.ndarray] = []
        output_tree = None
        for f, frame in enumerate(frames):
            for old in [k for k in trees if k < f - 1]:
                del trees[old]
            if not regions[f]:
                outputs.append(frame.copy())
                if colours is not None:
                    out_colours.append(np.asarray(colours[f], dtype=np.float64))
                output_tree = None  # same points as the input: its tree serves
                frame_done(f + 1, len(frames))
                continue
            neighbours: list[NeighbourFrame] = []
            if beta > 0:
                if f > 0:
                    # already inpainted: no holes left
                    prev_tree = output_tree if output_tree is not None else tree_of(f - 1)
                    neighbours.append(NeighbourFrame(outputs[f - 1], prev_tree, [], regions[f - 1],
                                                     out_colours[f - 1] if colours is not None else None))
                if f + 1 < len(frames):
                    neighbours.append(NeighbourFrame(frames[f + 1], tree_of(f + 1), regions[f + 1], regions[f + 1],
                                                     None if colours is None else
                                                     np.asarray(colours[f + 1], dtype=np.float64)))
            output, output_colours = self._inpaint_frame(frame, tree_of(f), regions[f], tuple(neighbours), unit,
                                                         voxelized, link_distance, slot,
                                                         None if colours is None else colours[f])
            outputs.append(output)
            if output_colours is not None:
                out_colours.append(output_colours)
            output_tree = cKDTree(outputs[f]) if beta > 0 and f + 1 < len(frames) and regions[f + 1] else None
            frame_done(f + 1, len(frames))
        return outputs, (out_colours if colours is not None else None)

    def _link_distance(self, frame: np.ndarray, tree: cKDTree, unit: float, voxel_data: bool) -> float:
        """Longest temporal link: ``link_radius`` point spacings, each at least one unit.

        A link joins a point to its counterpart in the neighbouring frame's sampling, so its length
        is measured in point spacings (one voxel on voxelized data), not in the cube's unit (see
        docs/notes-journal.md for the measurement on dfaust).
        """
        spacing = 1.0 if voxel_data else point_spacing(frame, tree=tree)
        return self.link_radius * max(unit, spacing)

    def _check_regions(self, f: int, frame: np.ndarray, frame_regions: list, unit: float, voxel_data: bool,
                       tree: cKDTree) -> None:
        """Refuse regions farther from ``frame`` than their size plus one cube and two point spacings
        (`holes.regions.check_regions_near`), and regions that cover every point.

        The spacings: a hole's centre lies within its size plus the sampling gap around it of the points left,
        and on a frame sparser than the cube (a few hundred points) that gap is longer than a cube.
        """
        if voxel_data:
            spacing = 1.0
        elif len(frame) >= 9:
            spacing = point_spacing(frame, tree=tree)
        else:  # too few points for a spacing: any region within the frame's extent belongs to it
            spacing = float(np.ptp(frame, axis=0).max()) if len(frame) else 0.0
        check_regions_near(frame, frame_regions, self.cube_size * unit + 2 * spacing, tree=tree, who=self.name,
                           frame_index=f)
        if union_mask(frame_regions, frame).all():
            raise UserError(f"{self.name}: frame {f}: the hole regions cover every point of the frame; "
                             "nothing is left to fill from")

    # -- one frame --------------------------------------------------------------------------
    def _inpaint_frame(self, points: np.ndarray, tree: cKDTree, regions: list, neighbours: tuple[NeighbourFrame, ...],
                       unit: float, voxelized: bool, link_distance: float | None, slot: float | None = None,
                       colours: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """Steps 1-10 of the module docstring on one frame (N, 3); returns the output frame and, given the frame's
        ``colours`` (N, 3), the output's colours (the known points' own, the new points' `cube_colours`; a voxel of
        step 10 its nearest new point's, whose tangent plane chose it), else None."""
        cube = self.cube_size * unit
        per = self.cells_per_cube
        cell = cube / per
        sigma = self.sigma * unit
        normals, agtv = normal_features(points, tree, sigma, self.feature_fraction)
        grid = CellGrid(points.min(axis=0), points.max(axis=0), cell, per, pad=per)
        candidates = CandidateCubes.build(grid, points, normals, agtv, regions, min_known_points=self.min_known_points,
                                          hole_free=self.hole_free_candidates, agtv_weight=self.agtv_weight)
        ctx = FrameContext(points, tree, grid, cube, cell, unit, sigma, candidates, neighbours, link_distance, slot,
                           None if colours is None else np.asarray(colours, dtype=np.float64))
        out = points.copy()
        new_points, new_colours = [], []
        for group in region_groups(regions, cube + cell):
            fill = self._fill_group(group, normals, agtv, ctx)
            out[fill.moved_index] = fill.moved_points
            new_points.append(fill.new)
            new_colours.append(np.full((len(fill.new), 3), np.nan) if fill.colours is None else fill.colours)
        added = np.vstack(new_points) if new_points else np.empty((0, 3))
        result = finish_frame(out, added, regions, voxelized=voxelized, round_known=self.known_points == "free")
        if colours is None:
            return result, None
        new = result[len(out):]
        carried = np.vstack(new_colours) if new_colours else np.empty((0, 3))
        if len(new) != len(added) or not np.array_equal(new, added):
            # step 10's voxels (none left where every new point fell on an occupied voxel)
            carried = carried[cKDTree(added).query(new)[1]] if len(new) else carried[:0]
        return result, np.vstack([np.asarray(colours, dtype=np.float64), carried])

    def _fill_group(self, regions: list, normals: np.ndarray, agtv: np.ndarray, ctx: FrameContext) -> GroupFill:
        """Fill one group of holes from the boundary inward (`methods._cubes.TargetCubeOrder`),
        one target cube at a time (`_fill_cube`), on the points of the group's box (`LocalPoints`)."""
        grid, cube, cell = ctx.grid, ctx.cube, ctx.cell
        points = ctx.points
        per = self.cells_per_cube
        reach = np.array([max(r.bounding_radius for r in regions)] * 3)
        lower = np.min([r.center for r in regions], axis=0) - reach - cube - cell
        upper = np.max([r.center for r in regions], axis=0) + reach + cube + cell
        a0 = np.clip(grid.cell_of(lower[None])[0], 0, grid.shape)
        a1 = np.clip(grid.cell_of(upper[None])[0] + 1, 0, grid.shape)
        if ((a1 - a0) < per).any():
            return GroupFill(np.empty(0, dtype=np.int64), np.empty((0, 3)), np.empty((0, 3)))
        window = tuple(slice(a, b) for a, b in zip(a0, a1))
        box_lower, box_upper = grid.cube_lower(a0), grid.cube_lower(a1)
        local_index = np.flatnonzero(((points >= box_lower) & (points < box_upper)).all(axis=1))
        local = LocalPoints(points[local_index].copy(), normals[local_index], agtv[local_index], local_index.copy(),
                            None if ctx.colours is None else ctx.colours[local_index])
        order = TargetCubeOrder(hole_cells(grid, regions)[window].copy(), grid.bin(points[local_index])[window].copy(),
                                per, self.min_known_points, self.rim_centred)
        fix_known = self.known_points == "fixed"
        while (pick := order.next()) is not None:
            if self.defer_unreachable and not order.reaches_pending(pick):
                # its pending cells are all away from its points: put off until points come nearer
                order.defer(pick)
                continue
            fill = self._fill_cube(grid.cube_lower(a0 + pick), regions, order.pending, a0, local, ctx, fix_known)
            local = local.apply(fill)
            order.filled(pick, grid.cell_of(fill.new) - a0)
        original = local.index >= 0
        # the new points as they are now: with known_points="free" a later target cube that holds
        # a point filled earlier solves it as a known row and may move it
        new = local.points[~original].copy()
        colours = None if local.colours is None else local.colours[~original]
        if fix_known:
            return GroupFill(np.empty(0, dtype=np.int64), np.empty((0, 3)), new, colours)
        return GroupFill(local.index[original], local.points[original], new, colours)

    def _fill_cube(self, lower: np.ndarray, regions: list, pending: np.ndarray, a0: np.ndarray, local: LocalPoints,
                   ctx: FrameContext, fix_known: bool) -> CubeFill:
        """Inpaint the target cube at ``lower`` (steps 4-9): sources, alignment, new points, graph,
        solve, drop_contradicted. Returns its new points and, with known_points="free", its moved
        known rows."""
        cube, unit = ctx.cube, ctx.unit
        in_cube = np.flatnonzero(in_box(local.points, lower, cube))
        target = local.points[in_cube]
        m = len(target)
        has_normal = ~np.isnan(local.agtv[in_cube])
        if m < self.min_known_points or not has_normal.any():
            return CubeFill(np.empty((0, 3)))
        dc_t = local.normals[in_cube][has_normal].mean(axis=0)
        agtv_t = local.agtv[in_cube][has_normal].mean()

        # inter-source cubes first (they need only the target's known points)
        beta = self._beta()
        inter: list[InterSource] = []
        if beta > 0:
            for neighbour in ctx.neighbours:
                found = inter_source(target, lower, neighbour, cube=cube, cell=ctx.cell, unit=unit,
                                     search_box=self.search_box, grow_source=self.grow_source,
                                     icp_iterations=self.icp_iterations)
                if found is not None:
                    inter.append(found)

        # intra-source cube; not searched when a raw inter-source cube already fits within half a
        # unit (it would win)
        fits = [c for c in inter if c.raw and c.residual <= 0.5 * unit]
        intra = None
        if not (self.temporal_source and fits):
            intra = intra_source(target, lower, np.concatenate([dc_t, [self.agtv_weight * agtv_t]]), ctx,
                                 intra_candidates=self.intra_candidates, hole_free=self.hole_free_candidates,
                                 grow_source=self.grow_source, cells_per_cube=self.cells_per_cube,
                                 agtv_weight=self.agtv_weight, icp_iterations=self.icp_iterations,
                                 residual=self.temporal_source)
        source = None if intra is None else intra.aligned
        source_colours = None  # an intra-source cube's colours are another place's (`cube_colours`)
        if self.temporal_source and inter:
            # an inter-source cube of captured data that fits the target better than the
            # intra-source cube provides the new points
            best = np.inf if intra is None else intra.residual
            for candidate in inter:
                if candidate.raw and candidate.residual < best:
                    source, best, source_colours = candidate.aligned, candidate.residual, candidate.colours
        if source is None:
            return CubeFill(np.empty((0, 3)))

        new = select_new_points(source, target, lower, regions, pending, ctx.grid.cell_of(source) - a0, cube=cube,
                                mode=self.new_points, slot=ctx.slot)
        if not len(new):
            return CubeFill(new)

        rows = np.vstack([target, new])
        known = np.zeros(len(rows), dtype=bool)
        known[:m] = True
        links = [] if ctx.link is None else [  # no link distance: no temporal terms, no inter-source cube
            temporal_links(rows, c.aligned, c.rotation, c.translation, c.regions, ctx.link,
                           link_cutoff=self.link_cutoff, skip_hole_links=self.skip_hole_links,
                           off_surface=self.off_surface) for c in inter]
        k = self.k_neighbors if self.k_neighbors is not None else max(1, int(round(np.sqrt(m))))
        laplacian = spatial_laplacian(rows, source, m, k, ctx.sigma, self.graph_on)
        result = solve_cube(rows, rows, known, laplacian, alpha=self.alpha, gamma=self.gamma, beta=beta,
                            temporal=[(link.counterpart, link.linked) for link in links], fix_known=fix_known)
        new = result[m:]
        colours = None
        if local.colours is not None:
            colours = cube_colours(rows, m, local.colours[in_cube], source, source_colours, inter, links, laplacian,
                                   alpha=self.alpha, gamma=self.gamma, beta=beta)
        if self.drop_contradicted and links:
            keep = uncontradicted(links, m)
            new, colours = new[keep], None if colours is None else colours[keep]
        if fix_known:
            return CubeFill(new, colours=colours)
        return CubeFill(new, in_cube, result[:m], colours)


class TemporalGraph(_CubeGraphInpainting):
    """The proposed method (Fu, Hu, Guo, ICME 2020): see the module docstring for every step.

    Two variants. ``variant="tuned"`` (the default) is ours: the paper's method plus additions that
    measured better (below). ``variant="paper"`` is the *paper configuration*: every step as the
    paper writes it, every addition of ours off. Each addition is a switch (a keyword parameter);
    a switch left at None takes the variant's value (`VARIANTS`), and a switch given explicitly
    overrides the variant (``TemporalGraph(variant="paper", known_points="fixed")`` is the paper
    configuration with that one change, and is no longer the paper configuration). `get_params`
    returns every switch resolved, so a run's record names each value it ran with.

    Parameters (lengths in units u, see the module docstring; the paper's values as defaults where
    the paper gives one): cube_size M = 20, cells_per_cube = 4 (step M/4), search_box H/M = 2.5,
    alpha = 1, beta = 0.5, gamma = 0.5, sigma = 1, k_neighbors = None (K = round(sqrt(m))).
    Switches, tuned / paper value:
      intra_candidates     4 / 1: the DC/AGTV-nearest candidates screened by alignment residual;
                           the paper takes the most similar cube (1).
      temporal_source      True / False: an inter-source cube of captured data that fits the target
                           better than the intra-source cube provides the new points; the paper's
                           new points always come from c_s_hat (Eq. 5, alpha term).
      drop_contradicted    True / False: drop new points a neighbour frame contradicts (off_surface,
                           link_radius tune it); the paper keeps every row of c_r.
      known_points         "fixed" / "fixed" ("free" in literal): "fixed" solves only the new rows
                           (the known rows stay at c_t); "free" solves every row, so the known rows
                           move too. Paper: fixed. Eq. (5)'s first term ties the known rows to c_t
                           ("ensures the desired cube to be close to c_t in the known region") and
                           "replace the target cube with the resulting cube" (l.364) fits both, but
                           only fixed fits the paper's results (fills that improve on the damaged
                           input, Hu ~10 dB above Lozes): free moves every known point of the 64
                           overlapping cubes around a hole again and again, ~6,000 of ~20,000 per
                           frame on the tiny human, and puts Hu 7.4 dB *below* no fill there (fixed:
                           +4.5 dB above; docs/paper-reading.md, decision 1).
      link_cutoff          True / False: a temporal link only within link_radius point spacings; the
                           paper links every point to its nearest neighbour (Eq. 4, weight 1).
      skip_hole_links      True / False: no temporal link for a row that maps into a hole region of
                           the (not yet inpainted) f+1; the paper links every row.
      rim_centred          True / False: prefer target cubes whose central 2x2x2 cells hold missing
                           data (centred on the rim); the paper: "choose the cube with missing data".
      defer_unreachable    True / False: put off a target cube whose points do not reach its missing
                           cells until fills come near; the paper has no deferral.
      hole_free_candidates True / False: intra-source candidates only among cubes touching no hole;
                           the paper: "the most similar cube ... in P_f" (any cube; the target and
                           the cubes overlapping it excepted, see below).
      grow_source          True / False: source and inter-source cubes grown by one cell (so that
                           they still cover the target after a rotation); the paper's cubes have
                           side M.
      new_points           "pending-cells" in both: the new points are the aligned source points in
                           the target cube that lie in a hole region (the paper's missing data) and
                           in a cell no earlier target cube of the frame covered: cubes are unions of
                           cells, and a cube replaced by c_r (the whole cube, l.364) holds no missing
                           slot any more, so this is what the paper's Omega implies, no mask beyond
                           it. "empty-slots" is the other reading (a source point in a hole region
                           whose voxel, by rounding, holds no point yet, one per voxel; a cell of
                           one point spacing on unvoxelized data): overlapping cubes whose sources
                           sit half a voxel apart then fill the same hole in layers (measured in
                           docs/notes-journal.md).
      graph_on             "estimate" / "source": the K-NN graph on the initial estimate
                           Omega_bar c_t + Omega c_s_hat, or, as the paper (Sec. 3.3, "we
                           approximate the connectivities via the similarities in its
                           intra-source cube"), on c_s_hat: a known row sits at its nearest
                           source point, a new row is a source point.
      snap                 "auto" / "auto" (False in literal): voxelized input gets its new points
                           turned into grid voxels (`voxelize_fill`) and, with known_points="free",
                           moved known points rounded. Paper: auto. The method extends [Fu18TIP],
                           which voxelizes the cloud as pre-processing, and the paper's data are
                           10-bit voxelized: its output lies on the integer grid
                           (docs/paper-reading.md, decision 2; off: +0.4-0.8 dB D1 lost on the tiny
                           human, 360 points a frame off the grid).
      feature_fraction     0.25 / 1.0: normals and AGTV on a fixed sample of the points (speed);
                           the paper computes them for every point.
    Other parameters (the same in both variants): spacing None (1 voxel for voxelized input,
    else 1/1024 of the largest bounding-box side: the paper sets M "according to the coordinate
    range"; "points": median 8th-NN distance / sqrt(2); or a number); link_radius 2.5 point
    spacings and off_surface 0.4 (used only by link_cutoff and drop_contradicted);
    min_known_points 16; icp_iterations 10; agtv_weight 1.

    The paper configuration, step by step (tex = /work/shared/paper/dynamic-pc-inpainting-icme2020.tex):
      - Cubes of side M = 20, step M/4 (tex l.143, a %-commented line), target cubes = cubes with
        missing data (l.144).
      - Holes larger than a cube are filled "in the inward order" (tex l.145, %-commented:
        "divide the hole into several small holes, and then inpaint the small holes in the inward
        order"): the target cube with the most known points (filled points count) goes first.
        How the inward order is realised is paper silent: this rule needs no hole geometry.
      - Filled points are known to the later target cubes and to frame f+1, whose f-1 is the
        inpainted output (tex l.364, %-commented: "the information of new points will be
        considered in the inpainting of the subsequent holes and subsequent frames").
      - Intra-source cube by DC and AGTV of the normals (l.146), structure matching by a
        simplified ICP (l.147); inter-source cubes by the box H = 2.5 M (l.373, %-commented) and
        the stride-1 sliding window (l.172); spatial graph on c_s_hat (l.189); K = sqrt(m)
        (l.373, %-commented), sigma = 1 (l.203), alpha = 1, beta = 0.5, gamma = 0.5 (l.341);
        Eq. (6) solved as a sparse system; the target cube replaced by c_r (l.364): its known rows
        held at c_t (the Omega_bar c_t term, weight 1, read as the data constraint; decision 1 of
        docs/paper-reading.md), its new rows as solved, on voxelized input as grid voxels
        ([Fu18TIP] voxelizes as pre-processing; decision 2).
    Paper silent, and the choice made (the same as the tuned variant's unless said; the evidence for
    each, with its ablation row, is in docs/paper-reading.md):
      - which cells are missing: the given hole regions, or in blind mode `holes.detection`
        (the paper's [Fu18TIP] detects holes automatically; the ICME paper does not say how);
      - min_known_points 16: a target cube needs known points to match (DC/AGTV, ICP) and to
        anchor the graph; each cube is a target at most once; nearby holes form one group;
      - DC/AGTV distance: Euclidean on (DC, AGTV) 4-vectors, PCA normals on 10 neighbours
        oriented away from the centroid, AGTV over 8 neighbours ([Fu18TIP] gives no formula for
        the distance);
      - an intra-source candidate must hold at least the target's m known points (it must cover
        the known part to supply the missing one) and must not overlap the target cube (the
        target is trivially most similar to itself, and overlapping cubes share its hole);
      - structure matching: translation to the target cube, then 10 iterations of trimmed
        point-to-point ICP from the target's known points ("simplified ICP");
      - inter-source votes: each known point's nearest neighbour in the frame, counted when it lies
        in the box (the same as the nearest neighbour within the box whenever the frame has a
        point within 0.75 M of the target point, i.e. on any continued surface);
      - rows of c_r: the known points, then the new points (slots: voxels; see new_points);
        the K-NN graph symmetrised by max(W, W^T);
      - first and last frame: one inter-source cube, beta counted once (per-row link counts in
        place of 2I); a one-frame sequence: spatial terms only, with a warning;
      - known points: fixed (Dirichlet rows at c_t; see known_points above);
      - output: on voxelized input the new points are voxels of the grid (snap "auto", see above);
        on unvoxelized input as solved.
    Precedence: an explicit keyword > the variant's value. `FuNonlocal` has the same variants (its
    paper configuration is this one without the temporal terms: beta = 0, [Fu18TIP] frame by frame).

    Measured figures behind the tuned variant's choices (and the commit each was measured at):
    docs/notes-journal.md.
    """

    name = "temporal-graph"
    summary = "temporal graph inpainting (Fu, Hu, Guo ICME 2020): intra- and inter-frame source cubes on a graph"
    version = "10"  # 2: link_radius in point spacings; 3: off_surface; 4: variants and switches, free-mode fix;
    # 5: ICP pairs independent of the CPU; 6: paper variant known points fixed + snap (variant literal added);
    # 7: colours solved on the cube's graph (`cube_colours`; the geometry unchanged); 8: the generic harmonic colour
    # fill without temporal terms (beta = 0, one frame); 9: ICP's stopping test in the data's unit; 10: integer data
    # sparser than a voxelization is not voxelized (CHANGELOG)
    uses_neighbour_frames = True
    _temporal = True

    def __init__(self, variant: str = "tuned", cube_size: float = 20.0, cells_per_cube: int = 4,
                 search_box: float = 2.5, alpha: float = 1.0, beta: float = 0.5, gamma: float = 0.5,
                 sigma: float = 1.0, k_neighbors: int | None = None, spacing: float | str | None = None,
                 known_points=None, min_known_points: int = 16, icp_iterations: int = 10,
                 link_radius: float = 2.5, snap=None, agtv_weight: float = 1.0, intra_candidates=None,
                 drop_contradicted=None, feature_fraction=None, temporal_source=None,
                 off_surface: float | None = 0.4, link_cutoff=None, skip_hole_links=None, rim_centred=None,
                 defer_unreachable=None, hole_free_candidates=None, grow_source=None, new_points=None,
                 graph_on=None):
        self.variant = variant
        self.cube_size = cube_size
        self.cells_per_cube = cells_per_cube
        self.search_box = search_box
        self.alpha = alpha
        self.beta = beta
        self.gamma = gamma
        self.sigma = sigma
        self.k_neighbors = k_neighbors
        self.spacing = spacing
        self.known_points = known_points
        self.min_known_points = min_known_points
        self.icp_iterations = icp_iterations
        self.link_radius = link_radius
        self.snap = snap
        self.agtv_weight = agtv_weight
        self.intra_candidates = intra_candidates
        self.feature_fraction = feature_fraction
        self.drop_contradicted = drop_contradicted
        self.temporal_source = temporal_source
        self.off_surface = off_surface
        self.link_cutoff = link_cutoff
        self.skip_hole_links = skip_hole_links
        self.rim_centred = rim_centred
        self.defer_unreachable = defer_unreachable
        self.hole_free_candidates = hole_free_candidates
        self.grow_source = grow_source
        self.new_points = new_points
        self.graph_on = graph_on


class FuNonlocal(_CubeGraphInpainting):
    """Hu, Fu, Guo [Fu18TIP] frame by frame: `TemporalGraph` without the temporal terms (beta = 0,
    no inter-source cubes). Same parameters otherwise, same defaults, same variants:
    ``variant="paper"`` is the paper configuration of Hu et al. as the ICME paper describes it
    (steps 1-3, the spatial part of 5, Eq. 6 with beta = 0), every addition of ours off."""

    name = "fu-nonlocal"
    summary = "non-local graph inpainting of each frame (Hu, Fu, Guo TIP 2019): temporal-graph with beta = 0"
    version = "8"  # 2: variants and switches, free-mode fix; 3: ICP pairs independent of the CPU;
    # 4: paper variant known points fixed + snap (variant literal added); 5: colours solved on the cube's graph
    # 6: without temporal terms the generic harmonic colour fill (the cube-by-cube solve measured worse);
    # 7: ICP's stopping test in the data's unit; 8: integer data sparser than a voxelization is not voxelized
    # (CHANGELOG)
    uses_neighbour_frames = False
    _temporal = False
    # not parameters: the temporal terms are off by definition, so there is no temporal evidence
    beta = 0.0
    drop_contradicted = False
    temporal_source = False
    off_surface = None
    link_cutoff = False
    skip_hole_links = False

    def __init__(self, variant: str = "tuned", cube_size: float = 20.0, cells_per_cube: int = 4,
                 alpha: float = 1.0, gamma: float = 0.5, sigma: float = 1.0, k_neighbors: int | None = None,
                 spacing: float | str | None = None, known_points=None, min_known_points: int = 16,
                 icp_iterations: int = 10, snap=None, agtv_weight: float = 1.0, intra_candidates=None,
                 feature_fraction=None, rim_centred=None, defer_unreachable=None, hole_free_candidates=None,
                 grow_source=None, new_points=None, graph_on=None):
        self.variant = variant
        self.cube_size = cube_size
        self.cells_per_cube = cells_per_cube
        self.alpha = alpha
        self.gamma = gamma
        self.sigma = sigma
        self.k_neighbors = k_neighbors
        self.spacing = spacing
        self.known_points = known_points
        self.min_known_points = min_known_points
        self.icp_iterations = icp_iterations
        self.snap = snap
        self.agtv_weight = agtv_weight
        self.intra_candidates = intra_candidates
        self.feature_fraction = feature_fraction
        self.rim_centred = rim_centred
        self.defer_unreachable = defer_unreachable
        self.hole_free_candidates = hole_free_candidates
        self.grow_source = grow_source
        self.new_points = new_points
        self.graph_on = graph_on
