"""The paper's temporal graph inpainting (`temporal-graph`) and its per-frame parent (`fu-nonlocal`).

Fu, Hu, Guo, "3D Dynamic Point Cloud Inpainting via Temporal Consistency on Graphs" (ICME 2020),
Sec. 3, built on Hu, Fu, Guo [Fu18TIP] (non-local self-similarity on graphs). One implementation:
`FuNonlocal` is `TemporalGraph` with the temporal terms switched off (beta = 0, no inter-source
cubes), so the two differ only by the temporal terms (tested: beta = 0 gives identical output).

Variants. ``variant="tuned"`` (the default) is ours; ``variant="paper"`` is the paper configuration
(every step as the paper writes it, every addition of ours off). The pipeline below is the tuned
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
   "free" is the paper's literal "replace the target cube with the resulting cube".
9. drop_contradicted [drop_contradicted]: a new point that an inter-source cube contradicts and none supports is
   dropped. Contradicted: no counterpart within ``link_radius`` although that frame has data there,
   and the point lies off that frame's surface (farther than ``off_surface`` link radii from the
   plane of its 8 nearest points there): a gap in a neighbour, e.g. in an inpainted f-1's own
   fill, is no evidence against a point on the surface continued.
10. Voxelized input (all coordinates integers) [snap]: the new points are turned into the grid voxels of
   the surface they sample (`_voxelize`: voxels within half a voxel of the local tangent plane),
   minus voxels already occupied.

Decisions by measurement: see the `TemporalGraph` docstring.
"""

from __future__ import annotations

import copy
import itertools
import warnings

import numpy as np
from scipy.spatial import cKDTree

from holes.geometry import point_spacing
from methods._cubes import CellGrid, best_window, block_sums, in_box
from methods._graph import knn_laplacian, solve_cube
from methods._registration import align_to_partial, alignment_residual
from methods.base import InpaintingMethod
from metrics.errors import UserError

_KNOWN_MODES = ("fixed", "free")
_NEW_POINT_MODES = ("pending-cells", "empty-slots")
_GRAPH_MODES = ("estimate", "source")

#: The values that each variant gives to the switches (parameters left at None). "tuned" is ours
#: (the defaults); "paper" follows the paper step by step, every addition of ours off (see the
#: `TemporalGraph` docstring, "The paper configuration", for each switch and the paper's text).
VARIANTS: dict[str, dict] = {
    "tuned": dict(intra_candidates=4, temporal_source=True, drop_contradicted=True, known_points="fixed",
                  link_cutoff=True, skip_hole_links=True, rim_centred=True, defer_unreachable=True,
                  hole_free_candidates=True, grow_source=True, new_points="pending-cells", snap="auto",
                  graph_on="estimate", feature_fraction=0.25),
    "paper": dict(intra_candidates=1, temporal_source=False, drop_contradicted=False, known_points="free",
                  link_cutoff=False, skip_hole_links=False, rim_centred=False, defer_unreachable=False,
                  hole_free_candidates=False, grow_source=False, new_points="pending-cells", snap=False,
                  graph_on="source", feature_fraction=1.0),
}


class _CubeGraphInpainting(InpaintingMethod):
    """Shared machinery; subclasses fix whether the temporal terms are used (``_temporal``)."""

    _temporal: bool = True
    detects_holes = True
    needs_regions = False

    # -- parameters -------------------------------------------------------------------------
    def _beta(self) -> float:
        return float(self.beta) if self._temporal else 0.0

    # -- variant ----------------------------------------------------------------------------
    def get_params(self) -> dict:
        """The constructor parameters with every switch left at None replaced by the variant's value
        (so a stored record names each switch as it ran). An unknown variant leaves them at None
        (`inpaint` refuses it)."""
        params = super().get_params()
        for name, value in VARIANTS.get(params.get("variant"), {}).items():
            if name in params and params[name] is None:
                params[name] = value
        return params

    def _configured(self) -> "_CubeGraphInpainting":
        """A copy whose switches hold their resolved values (explicit ones win over the variant's)."""
        if self.variant not in VARIANTS:
            raise ValueError(f"{self.name}: variant must be one of {tuple(VARIANTS)}, got {self.variant!r}")
        run = copy.copy(self)
        run.__dict__.update(self.get_params())
        return run

    def validate_params(self) -> "_CubeGraphInpainting":
        """As `InpaintingMethod.validate_params`, on the switches as the variant resolves them (a switch
        left at None takes the variant's value, so None itself is never checked)."""
        try:
            run = self._configured()
        except ValueError as err:  # an unknown variant
            raise UserError(str(err)) from None
        InpaintingMethod.validate_params(run)
        return self

    def _validate(self) -> None:
        def positive(name):
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

    # -- sequence ---------------------------------------------------------------------------
    def inpaint(self, frames, regions=None):
        frames, regions = self._check_inputs(frames, regions)
        return self._configured()._inpaint_sequence(frames, regions)

    def _inpaint_sequence(self, frames, regions):
        self._validate()
        trees: dict = {}  # k-d tree of each input frame, built once, dropped once behind

        def tree_of(f):
            if f not in trees:
                trees[f] = cKDTree(frames[f])
            return trees[f]

        integer = all(np.array_equal(f, np.round(f)) for f in frames)
        voxelized = self.snap is True or (self.snap == "auto" and integer)
        largest = max(range(len(frames)), key=lambda f: len(frames[f]))
        if self.spacing == "points":
            unit = point_spacing(frames[largest], tree=tree_of(largest))
        elif self.spacing is not None:
            unit = float(self.spacing)
        elif integer:
            unit = 1.0  # one voxel, whatever the bit depth
        else:
            # the paper sets M "according to the coordinate range of P_f": one unit is 1/1024 of
            # the largest bounding-box side (M = 20 on a body 1023 units tall)
            extent = float(np.ptp(frames[largest], axis=0).max())
            if not extent > 0:
                raise UserError(f"{self.name}: the frames have zero extent; pass spacing=<length of one unit>")
            unit = extent / 1024.0
        if regions is None:
            from holes.detection import detect_holes  # lazily: blind protocol only

            regions = [list(detect_holes(frame)) for frame in frames]
        for f in range(len(frames)):
            if regions[f]:
                self._check_regions(f, frames[f], regions[f], unit, tree_of(f))
        beta = self._beta()
        link_distance = self._link_distance(frames[largest], tree_of(largest), unit, integer) if beta > 0 else None
        # a slot of the paper's M^3 grid of a cube: one voxel; on unvoxelized data one point spacing
        slot = None
        if self.new_points == "empty-slots":
            slot = unit if integer else max(unit, point_spacing(frames[largest], tree=tree_of(largest)))
        if beta > 0 and len(frames) == 1:
            warnings.warn(f"{self.name}: a one-frame sequence has no neighbouring frames; "
                          "using the spatial terms only (as fu-nonlocal)", stacklevel=2)
        outputs: list[np.ndarray] = []
        output_tree = None
        for f, frame in enumerate(frames):
            for old in [k for k in trees if k < f - 1]:
                del trees[old]
            if not regions[f]:
                outputs.append(frame.copy())
                output_tree = None  # same points as the input: its tree serves
                continue
            neighbours = []
            if beta > 0:
                if f > 0:
                    # already inpainted: no holes left
                    prev_tree = output_tree if output_tree is not None else tree_of(f - 1)
                    neighbours.append(dict(points=outputs[f - 1], tree=prev_tree, regions=[],
                                           source_regions=regions[f - 1]))
                if f + 1 < len(frames):
                    neighbours.append(dict(points=frames[f + 1], tree=tree_of(f + 1), regions=regions[f + 1],
                                           source_regions=regions[f + 1]))
            outputs.append(self._inpaint_frame(frame, tree_of(f), regions[f], neighbours, unit, voxelized,
                                               link_distance, slot))
            output_tree = cKDTree(outputs[f]) if beta > 0 and f + 1 < len(frames) and regions[f + 1] else None
        return outputs

    def _link_distance(self, frame, tree, unit, integer) -> float:
        """Longest temporal link: ``link_radius`` point spacings, each at least one unit.

        A link joins a point to its counterpart in the neighbouring frame's sampling, so its length
        is measured in point spacings (one voxel on voxelized data), not in the cube's unit: on
        dfaust (u = 1, spacing 3.1) a link of 2.5 u dropped half the fill of coherent holes as
        "contradicted" (10 frames, medium coherent holes: D1 20.4 -> 25.0 dB with 2.5 spacings).
        """
        spacing = 1.0 if integer else point_spacing(frame, tree=tree)
        return self.link_radius * max(unit, spacing)

    def _check_regions(self, f, frame, frame_regions, unit, tree):
        reach = self.cube_size * unit
        inside = np.zeros(len(frame), dtype=bool)
        for region in frame_regions:
            dist, _ = tree.query(region.center)
            if dist > region.bounding_radius + reach:
                raise UserError(
                    f"{self.name}: frame {f}: hole region centred at {np.round(region.center, 3).tolist()} "
                    f"is {dist:.3g} away from the nearest point, farther than its size plus one cube "
                    f"({region.bounding_radius + reach:.3g}); the regions do not belong to this cloud "
                    "(wrong holes.json or wrong frame order?)")
            inside |= region.contains(frame)
        if inside.all():
            raise UserError(f"{self.name}: frame {f}: the hole regions cover every point of the frame; "
                             "nothing is left to fill from")

    # -- one frame --------------------------------------------------------------------------
    def _normal_features(self, points: np.ndarray, tree: cKDTree, sigma: float) -> tuple[np.ndarray, np.ndarray]:
        """Unit normals (N, 3) and per-point AGTV a_i (N,) on a fixed sample of the points, NaN elsewhere.

        The sample is a fixed-seed ``feature_fraction`` of the points (all of them at 1.0). Normal of a
        sampled point: the eigenvector of the smallest eigenvalue of the covariance of its 10 nearest
        points in the whole frame, oriented away from the frame centroid. Written with numpy (batched
        ``eigh``) instead of open3d's ``estimate_normals`` because open3d can only estimate the normals
        of every point, and the AGTV needs the neighbour search anyway. AGTV of a sampled point:
        a_i = sum_{j in 8-NN of i in the sample} exp(-||p_i - p_j||^2 / 2 sigma_s^2) ||n_i - s_ij n_j||_1,
        s_ij = sign(n_i . n_j), sigma_s = sigma / sqrt(feature_fraction) (the sample's spacing grows
        as 1 / sqrt(fraction) on a surface).
        """
        n = len(points)
        count = max(min(n, 9), int(round(self.feature_fraction * n)))
        sample = np.sort(np.random.default_rng(0).choice(n, count, replace=False)) if count < n else np.arange(n)
        sampled = points[sample]
        _, idx = tree.query(sampled, k=min(10, n), workers=-1)
        neigh = points[idx]
        neigh -= neigh.mean(axis=1, keepdims=True)
        cov = np.einsum("nki,nkj->nij", neigh, neigh)
        _, vectors = np.linalg.eigh(cov)
        sample_normals = vectors[:, :, 0]
        flip = np.einsum("ij,ij->i", sample_normals, sampled - points.mean(axis=0)) < 0
        sample_normals[flip] *= -1.0
        k = min(9, count)
        dist, nbr = cKDTree(sampled).query(sampled, k=k, workers=-1)
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

    def _inpaint_frame(self, points, tree, regions, neighbours, unit, voxelized, link_distance, slot=None):
        cube = self.cube_size * unit
        per = self.cells_per_cube
        cell = cube / per
        sigma = self.sigma * unit
        normals, agtv = self._normal_features(points, tree, sigma)
        grid = CellGrid(points.min(axis=0), points.max(axis=0), cell, per, pad=per)

        # candidate (intra-source) cubes: per-cube sums from per-cell sums (summed-volume tables)
        counts = grid.bin(points)
        hole_cells = self._hole_cells(grid, regions)
        cube_counts = grid.cube_sums(counts)
        cube_holes = grid.cube_sums(hole_cells.astype(np.int64))
        ok = cube_counts >= self.min_known_points
        if self.hole_free_candidates:
            ok &= cube_holes == 0
        sampled = ~np.isnan(agtv)
        sample_counts = grid.cube_sums(grid.bin(points[sampled]))
        ok &= sample_counts > 0
        anchors = np.argwhere(ok)
        cand_count = cube_counts[ok].astype(np.float64)
        cand_samples = sample_counts[ok].astype(np.float64)
        cand_dc = grid.cube_sums(grid.bin(points[sampled], normals[sampled]))[ok] / cand_samples[:, None]
        cand_agtv = grid.cube_sums(grid.bin(points[sampled], agtv[sampled]))[ok] / cand_samples
        candidates = dict(lower=grid.cube_lower(anchors), count=cand_count, dc=cand_dc, agtv=cand_agtv,
                          tree=cKDTree(np.column_stack([cand_dc, self.agtv_weight * cand_agtv])) if len(anchors) else None)

        context = dict(points=points, tree=tree, grid=grid, cube=cube, cell=cell, unit=unit, sigma=sigma,
                       candidates=candidates, neighbours=neighbours, link=link_distance, slot=slot)
        out = points.copy()
        new_points = []
        for group in self._region_groups(regions, cube + cell):
            moved, added = self._fill_group(group, normals, agtv, context)
            for index, position in moved:
                out[index] = position
            new_points.append(added)
        added = np.vstack(new_points) if new_points else np.empty((0, 3))
        if voxelized and len(added):
            if self.known_points == "free":
                out = np.floor(out + 0.5)
            added = self._voxelize(added, regions)
            dist, _ = cKDTree(out).query(added, distance_upper_bound=0.5)
            added = added[~np.isfinite(dist)]
        return np.vstack([out, added])

    @staticmethod
    def _voxelize(added: np.ndarray, regions) -> np.ndarray:
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

    @staticmethod
    def _hole_cells(grid: CellGrid, regions) -> np.ndarray:
        """Bool (X, Y, Z): cells that touch a hole region (cell centre within region + half diagonal)."""
        mask = np.zeros(tuple(grid.shape), dtype=bool)
        half_diag = grid.cell * np.sqrt(3.0) / 2.0
        for region in regions:
            r = region.bounding_radius + half_diag
            lo = np.clip(grid.cell_of((region.center - r)[None])[0], 0, grid.shape)
            hi = np.clip(grid.cell_of((region.center + r)[None])[0] + 1, 0, grid.shape)
            if (hi <= lo).any():
                continue
            idx = np.stack(np.meshgrid(*[np.arange(a, b) for a, b in zip(lo, hi)], indexing="ij"), -1).reshape(-1, 3)
            centres = grid.origin + (idx + 0.5) * grid.cell
            hit = idx[region.contains(centres, margin=half_diag)]
            mask[tuple(hit.T)] = True
        return mask

    @staticmethod
    def _region_groups(regions, reach: float) -> list[list]:
        """Regions grouped so that groups are farther apart than ``reach`` (single linkage)."""
        n = len(regions)
        label = list(range(n))

        def root(i):
            while label[i] != i:
                label[i] = label[label[i]]
                i = label[i]
            return i

        for i in range(n):
            for j in range(i + 1, n):
                gap = np.linalg.norm(regions[i].center - regions[j].center)
                if gap <= regions[i].bounding_radius + regions[j].bounding_radius + 2 * reach:
                    label[root(i)] = root(j)
        groups: dict[int, list] = {}
        for i in range(n):
            groups.setdefault(root(i), []).append(regions[i])
        return list(groups.values())

    def _fill_group(self, regions, normals, agtv, ctx):
        """Fill one group of holes from the boundary inward. Returns (moved known points
        [(frame index, position)], new points (P, 3))."""
        grid, cube, cell = ctx["grid"], ctx["cube"], ctx["cell"]
        points = ctx["points"]
        per = self.cells_per_cube
        reach = np.array([max(r.bounding_radius for r in regions)] * 3)
        lower = np.min([r.center for r in regions], axis=0) - reach - cube - cell
        upper = np.max([r.center for r in regions], axis=0) + reach + cube + cell
        a0 = np.clip(grid.cell_of(lower[None])[0], 0, grid.shape)
        a1 = np.clip(grid.cell_of(upper[None])[0] + 1, 0, grid.shape)
        if ((a1 - a0) < per).any():
            return [], np.empty((0, 3))
        window = tuple(slice(a, b) for a, b in zip(a0, a1))
        pending = self._hole_cells(grid, regions)[window].copy()
        box_lower, box_upper = grid.cube_lower(a0), grid.cube_lower(a1)
        local_index = np.flatnonzero(((points >= box_lower) & (points < box_upper)).all(axis=1))
        local = dict(points=points[local_index].copy(), normals=normals[local_index], agtv=agtv[local_index],
                     index=local_index.copy())
        local_counts = grid.bin(points[local_index])[window].copy()
        fix_known = self.known_points == "fixed"
        # Per-cube sums over the local window, kept up to date around each filled cube only.
        # central: pending cells in the cube's central (per/2)^3 block; a target cube is centred on
        # the hole's rim, so about half of it is known (for the matching) and half missing.
        c0 = per // 4
        cw = per - 2 * c0
        n_anchor = np.array(pending.shape) - per + 1
        sums = {}

        def refresh(lo, hi):
            lo = np.maximum(lo, 0)
            hi = np.minimum(hi, n_anchor)
            if (hi <= lo).any():
                return
            cells = tuple(slice(a, b + per - 1) for a, b in zip(lo, hi))
            anchors = tuple(slice(a, b) for a, b in zip(lo, hi))
            centre = tuple(slice(a + c0, b + c0 + cw - 1) for a, b in zip(lo, hi))
            sums["pending"][anchors] = block_sums(pending[cells].astype(np.int64), per)
            sums["known"][anchors] = block_sums(local_counts[cells], per)
            sums["central"][anchors] = block_sums(pending[centre].astype(np.int64), cw)

        for key in ("pending", "known", "central"):
            sums[key] = np.zeros(tuple(n_anchor), dtype=np.int64)
        refresh(np.zeros(3, dtype=np.int64), n_anchor)
        tried = np.zeros(tuple(n_anchor), dtype=bool)  # each cube is a target at most once
        # a cube whose pending cells are all away from its points is put off until points come
        # nearer (its known count grows): the missing surface cannot be reached from it yet
        deferred = np.full(tuple(n_anchor), -1, dtype=np.int64)
        while True:
            enough = (sums["known"] >= self.min_known_points) & ~tried & (sums["known"] > deferred)
            eligible = (sums["central"] > 0) & enough if self.rim_centred else np.zeros_like(enough)
            if not eligible.any():
                # no known-rich cube is centred on the hole any more (or rim_centred is off): any
                # cube with missing data
                eligible = (sums["pending"] > 0) & enough
                if not eligible.any():
                    break
            # the target cube with the most known data first: holes fill from the rim inward
            pick = np.array(np.unravel_index(np.argmax(np.where(eligible, sums["known"], -1)), eligible.shape))
            lower = grid.cube_lower(a0 + pick)
            if self.defer_unreachable and not self._reaches_pending(pending, local_counts, pick):
                deferred[tuple(pick)] = sums["known"][tuple(pick)]
                continue
            new = self._fill_cube(lower, regions, pending, a0, local, ctx, fix_known)
            tried[tuple(pick)] = True
            if len(new):
                cells = grid.cell_of(new) - a0
                keep = ((cells >= 0) & (cells < local_counts.shape)).all(axis=1)
                np.add.at(local_counts, tuple(cells[keep].T), 1)
                local["points"] = np.vstack([local["points"], new])
                nan = np.full((len(new), 3), np.nan)
                local["normals"] = np.vstack([local["normals"], nan])
                local["agtv"] = np.concatenate([local["agtv"], nan[:, 0]])
                local["index"] = np.concatenate([local["index"], np.full(len(new), -1)])
            pending[tuple(slice(p, p + per) for p in pick)] = False
            refresh(pick - per + 1, pick + per)
        original = local["index"] >= 0
        moved = [] if fix_known else list(zip(local["index"][original], local["points"][original]))
        # the new points as they are now: with known_points="free" a later target cube that holds
        # a point filled earlier solves it as a known row and may move it (local["points"] is kept
        # up to date; the positions at the time of filling would be stale)
        return moved, local["points"][~original].copy()

    def _reaches_pending(self, pending, counts, pick) -> bool:
        """True when, inside the cube anchored at local cell ``pick``, a cell holding points is a
        pending cell or touches one (26-neighbourhood): the surface reaches the missing part."""
        per = self.cells_per_cube
        block = tuple(slice(p, p + per) for p in pick)
        hole = pending[block]
        if not hole.any():
            return False
        near = np.zeros((per + 2,) * 3, dtype=bool)
        for dx, dy, dz in itertools.product(range(3), repeat=3):
            near[dx:dx + per, dy:dy + per, dz:dz + per] |= hole
        return bool((near[1:-1, 1:-1, 1:-1] & (counts[block] > 0)).any())

    def _fill_cube(self, lower, regions, pending, a0, local, ctx, fix_known) -> np.ndarray:
        """Inpaint the target cube at ``lower``; returns its new points (P, 3) (known points moved
        in place in ``local`` when known_points='free')."""
        cube, cell, unit, grid = ctx["cube"], ctx["cell"], ctx["unit"], ctx["grid"]
        in_cube = np.flatnonzero(in_box(local["points"], lower, cube))
        target = local["points"][in_cube]
        m = len(target)
        has_normal = ~np.isnan(local["agtv"][in_cube])
        if m < self.min_known_points or not has_normal.any():
            return np.empty((0, 3))
        dc_t = local["normals"][in_cube][has_normal].mean(axis=0)
        agtv_t = local["agtv"][in_cube][has_normal].mean()

        # inter-source cubes first (they need only the target's known points)
        beta = self._beta()
        inter = []
        if beta > 0:
            for neighbour in ctx["neighbours"]:
                found = self._inter_source(target, lower, neighbour, ctx)
                if found is not None:
                    inter.append(found)

        # intra-source cube: most similar DC/AGTV among hole-free cubes holding >= m points; not
        # searched when a raw inter-source cube already fits within half a unit (it would win)
        fits = [c for c in inter if c["raw"] and c["residual"] <= 0.5 * unit]
        found = None if (self.temporal_source and fits) else self._intra_source(lower, target, dc_t, agtv_t, ctx)
        source = None if found is None else found[0]
        if self.temporal_source and inter:
            # an inter-source cube of captured data (no hole of its input frame near the target)
            # that fits the target better than the intra-source cube provides the new points
            best = np.inf if found is None else found[1]
            for candidate in inter:
                if candidate["raw"] and candidate["residual"] < best:
                    source, best = candidate["aligned"], candidate["residual"]
        if source is None:
            return np.empty((0, 3))

        # new points: aligned source points in the missing part of the target cube
        cells = grid.cell_of(source) - a0
        in_window = ((cells >= 0) & (cells < pending.shape)).all(axis=1)
        in_pending = np.zeros(len(source), dtype=bool)
        in_pending[in_window] = pending[tuple(cells[in_window].T)]
        inside = np.zeros(len(source), dtype=bool)
        for region in regions:
            inside |= region.contains(source)
        inside &= in_box(source, lower, cube)
        if self.new_points == "pending-cells":
            new = source[in_pending & inside]
        else:
            # "empty-slots" (the other reading of Omega, the missing slots of the M^3 grid): a
            # source point in a hole region whose slot (voxel of side ``slot``, by rounding) holds
            # no point of the frame yet, captured or filled by an earlier target cube; one per slot
            new = source[inside]
            if len(new):
                slots = np.floor(new / ctx["slot"] + 0.5).astype(np.int64)
                taken = {tuple(key) for key in np.floor(target / ctx["slot"] + 0.5).astype(np.int64)}
                _, first = np.unique(slots, axis=0, return_index=True)
                new = new[[i for i in np.sort(first) if tuple(slots[i]) not in taken]].reshape(-1, 3)
        if not len(new):
            return new

        rows = np.vstack([target, new])
        known = np.zeros(len(rows), dtype=bool)
        known[:m] = True
        temporal, contradicted, support = [], [], []
        for candidate in inter:
            counterpart, linked, against, near = self._temporal_links(rows, candidate, ctx["link"])
            temporal.append((counterpart, linked))
            contradicted.append(against)
            support.append(near)
        k = self.k_neighbors if self.k_neighbors is not None else max(1, int(round(np.sqrt(m))))
        if self.graph_on == "source":
            # the paper: the spatial graph is the K-NN graph of the intra-source cube c_s_hat; a
            # known row sits at its counterpart there (nearest in relative location), a new row
            # is a source point itself
            _, nearest = cKDTree(source).query(target)
            laplacian = knn_laplacian(np.vstack([source[nearest], new]), k, ctx["sigma"])
        else:
            laplacian = knn_laplacian(rows, k, ctx["sigma"])
        result = solve_cube(rows, rows, known, laplacian, alpha=self.alpha, gamma=self.gamma, beta=beta,
                            temporal=temporal, fix_known=fix_known)
        if not fix_known:
            local["points"][in_cube] = result[:m]
        new = result[m:]
        if self.drop_contradicted and temporal:
            # a new point that a neighbouring frame contradicts and none supports is dropped
            supported = np.any([near[m:] for near in support], axis=0)
            against = np.any([c[m:] for c in contradicted], axis=0)
            new = new[supported | ~against]
        return new

    def _intra_source(self, lower, target, dc_t, agtv_t, ctx):
        """The aligned intra-source points (S, 3) and their residual for the target cube at
        ``lower``, or None.

        Candidates: hole-free cubes with at least as many points as the target's known part,
        ranked by the Euclidean distance of (DC, agtv_weight * AGTV) (a 4D k-d tree over all
        candidates of the frame). The best ``intra_candidates`` are aligned (the paper: 1); with
        more, the one with the smallest trimmed mean alignment residual wins.
        """
        cand, cube, cell = ctx["candidates"], ctx["cube"], ctx["cell"]
        m = len(target)
        if not len(cand["count"]):
            return None
        query = np.concatenate([dc_t, [self.agtv_weight * agtv_t]])
        usable = cand["count"] >= m
        if not self.hole_free_candidates:
            # candidates may hold holes, but not the target cube itself nor a cube overlapping it
            # (up to (2 per - 1)^3 of them): they share its hole, and the target is trivially the
            # most similar to itself (paper silent)
            usable &= (np.abs(cand["lower"] - lower) >= cube - 0.5 * cell).any(axis=1)
        k = min(len(cand["count"]), 64 if self.hole_free_candidates else 64 + (2 * self.cells_per_cube - 1) ** 3)
        _, order = cand["tree"].query(query, k=k)
        order = np.atleast_1d(order)
        order = order[usable[order]]
        if len(order) < self.intra_candidates:
            # rare: few big-enough cubes among the nearest features; rank all of them
            big = np.flatnonzero(usable)
            if not len(big):
                return None
            feats = np.column_stack([cand["dc"][big], self.agtv_weight * cand["agtv"][big]])
            order = big[np.argsort(np.linalg.norm(feats - query, axis=1), kind="stable")]
        half = cube / 2.0
        # grown by one cell: the source still covers the target cube after the alignment rotates it
        grow = cell if self.grow_source else 0.0
        choices = order[: self.intra_candidates]
        # with several candidates: a short alignment of each screens them, the winner is refined
        screen = self.icp_iterations if len(choices) == 1 else min(3, self.icp_iterations)
        best, best_residual = None, np.inf
        for index in choices:
            source_lower = cand["lower"][index]
            source_idx = ctx["tree"].query_ball_point(source_lower + half, half + grow, p=np.inf)
            if len(source_idx) < 3:
                continue
            source = ctx["points"][source_idx] + (lower - source_lower)
            source_tree = cKDTree(source)
            rotation, translation = align_to_partial(source, target, iterations=screen, source_tree=source_tree)
            residual = 0.0 if len(choices) == 1 else alignment_residual(source_tree, target, rotation, translation)
            if residual < best_residual:
                best, best_residual = (source, source_tree, rotation, translation), residual
        if best is None:
            return None
        source, source_tree, rotation, translation = best
        if screen < self.icp_iterations:
            rotation, translation = align_to_partial(source, target, iterations=self.icp_iterations - screen,
                                                     source_tree=source_tree, start=(rotation, translation))
        residual = alignment_residual(source_tree, target, rotation, translation) if self.temporal_source else 0.0
        return source @ rotation.T + translation, residual

    def _inter_source(self, target, lower, neighbour, ctx):
        """The aligned inter-source cube of one neighbouring frame for the target cube at ``lower``
        (a dict: aligned points, R, t, residual, raw, regions), or None when the frame has no points
        near the target cube."""
        cube, cell, unit = ctx["cube"], ctx["cell"], ctx["unit"]
        box = self.search_box * cube
        centre = lower + cube / 2.0
        box_lower = centre - box / 2.0
        # nearest neighbour of each target point in the box: the frame's nearest neighbour when it
        # lies in the box (a point whose nearest neighbour is outside has no counterpart in the box
        # near it and does not vote)
        _, nearest = neighbour["tree"].query(target)
        votes = neighbour["points"][nearest]
        votes = votes[in_box(votes, box_lower, box)]
        if len(votes) < 3:
            return None
        window_lower, _ = best_window(votes, box_lower, box, cube, unit)
        half = cube / 2.0
        window_idx = neighbour["tree"].query_ball_point(window_lower + half, half + (cell if self.grow_source else 0.0),
                                                        p=np.inf)
        if len(window_idx) < 3:
            return None
        source = neighbour["points"][window_idx]
        source_tree = cKDTree(source)
        rotation, translation = align_to_partial(source, target, iterations=self.icp_iterations,
                                                 source_tree=source_tree)
        residual = alignment_residual(source_tree, target, rotation, translation)
        # raw: no hole of that frame's input comes within one cube of the target, so its points
        # there are captured data (an inpainted f-1 would otherwise hand its own fill on, and a
        # fill copied from frame to frame shrinks and drifts with the hole)
        raw = all(np.linalg.norm(r.center - centre) > r.bounding_radius + cube for r in neighbour["source_regions"])
        return dict(aligned=source @ rotation.T + translation, rotation=rotation, translation=translation,
                    residual=residual, raw=raw, regions=neighbour["regions"])

    def _temporal_links(self, rows, inter, link_distance):
        """(counterpart (n, 3), linked (n,), contradicted (n,), supported (n,)) of the rows in one
        aligned inter-source cube: the nearest neighbour in relative location. supported: within
        ``link_distance`` and not mapped into a hole region of that frame; contradicted: neither
        within ``link_distance`` nor mapped into a hole. linked: every row (the paper), or with
        link_cutoff only rows within ``link_distance``, and with skip_hole_links not rows mapped
        into a hole of that frame."""
        aligned = inter["aligned"]
        aligned_tree = cKDTree(aligned)
        dist, idx = aligned_tree.query(rows)
        near = dist <= link_distance
        in_hole = np.zeros(len(rows), dtype=bool)
        if inter["regions"]:
            # rows that land in a hole of the (not yet inpainted) neighbour have no true counterpart
            back = (rows - inter["translation"]) @ inter["rotation"]
            for region in inter["regions"]:
                in_hole |= region.contains(back)
        # the paper links every row to its nearest neighbour (link_cutoff=False, skip_hole_links=False)
        linked = near.copy() if self.link_cutoff else np.ones(len(rows), dtype=bool)
        if self.skip_hole_links:
            linked &= ~in_hole
        near &= ~in_hole  # a counterpart that supports the row (drop_contradicted)
        # contradicted: the neighbour has data there but none of it near the row. Also an inpainted
        # f-1: letting only captured data contradict was measured worse (human, 10 frames, D1
        # 24.83 -> 23.92 dB independent holes, 19.51 -> 16.39 dB coherent holes)
        contradicted = ~near & ~in_hole
        if self.off_surface is not None and contradicted.any() and len(aligned) >= 3:
            # a gap in the neighbour (an inpainted fill may have one) is no evidence against a row
            # that lies on the neighbour's surface continued; only a row off that surface is
            cand = np.flatnonzero(contradicted)
            _, nb = aligned_tree.query(rows[cand], k=min(8, len(aligned)))
            patch = aligned[nb]
            centre = patch.mean(axis=1)
            spread = patch - centre[:, None, :]
            normal = np.linalg.eigh(np.einsum("nki,nkj->nij", spread, spread))[1][:, :, 0]
            off = np.abs(np.einsum("ij,ij->i", rows[cand] - centre, normal))
            contradicted[cand] = off > self.off_surface * link_distance
        return aligned[idx], linked, contradicted, near


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
      known_points         "fixed" / "free": "fixed" solves only the new rows; "free" is the paper's
                           "replace the target cube with the resulting cube" (known rows move too).
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
                           sit half a voxel apart then fill the same hole in layers (the test
                           sphere, radius 9 hole, 359 points removed: 888 new points against 259
                           with "pending-cells", radial error 0.43 against 0.24 voxel).
      graph_on             "estimate" / "source": the K-NN graph on the initial estimate
                           Omega_bar c_t + Omega c_s_hat, or, as the paper (Sec. 3.3, "we
                           approximate the connectivities via the similarities in its
                           intra-source cube"), on c_s_hat: a known row sits at its nearest
                           source point, a new row is a source point.
      snap                 "auto" / False: voxelized input gets its new points turned into grid
                           voxels (`_voxelize`) and, with known_points="free", moved known points
                           rounded; the paper says nothing of quantizing the output (False).
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
        Eq. (6) solved as a sparse system; the target cube replaced by c_r (l.364).
    Paper silent, and the choice made (the same as the tuned variant's unless said):
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
      - output: new points as solved, no quantization (snap False).
    Precedence: an explicit keyword > the variant's value. `FuNonlocal` has the same variants (its
    paper configuration is this one without the temporal terms: beta = 0, [Fu18TIP] frame by frame).

    Decisions by measurement (scratch runs; embedded human, size "small" (~96k points a frame,
    10-bit voxels), 4 frames, medium region holes (holes.synthetic preset, seed 0), metrics with
    the intrinsic peak, whole-frame GPSNR D1 / D2 in dB and NSHD; before temporal_source existed):
      paper-like (1 candidate, no dropping, link 5, fixed)   D1 14.70  D2 15.11  NSHD 5.10e-9
      same, known_points="free"                              D1 15.14  D2 16.75  NSHD 4.18e-9
        (but frame-level temporal consistency 0.057 vs 0.027: moved known points flicker)
      4 candidates + drop_contradicted                       D1 20.02  D2 21.36  NSHD 1.88e-9
      4 candidates + drop_contradicted, "free"               D1 16.32  D2 20.71  NSHD 1.99e-9
      4 candidates + drop_contradicted, link_radius 2.5      D1 19.95  D2 23.59  NSHD 1.18e-9
      fu-nonlocal 1 / 4 / 8 candidates                       D1 14.75 / 16.29 / 16.10
      no fill                                                D1  7.59  D2 27.49  NSHD 7.03e-9
    temporal_source, one frame with 3 medium holes between intact neighbours: mean distance of
    the new points to the true surface 0.82 -> 0.55 voxel (median 1 -> 0). spacing on
    dfaust_50004_punching (unvoxelized, 1023 tall, 100k points): "points" gives u = 3.14
    (M = 63) and a hole-region D2 RMS of 7.4 for fu-nonlocal, against 2.7 with u = 1 (M = 20).
    link_radius in point spacings (version 2) and off_surface (version 3), 10 frames, medium region
    holes seed 0, whole-frame D1 / D2 dB, NSHD: link 2.5 u -> 2.5 spacings on dfaust coherent holes
    20.38/33.05/2.78e-9 -> 25.00/29.75/1.62e-9 (voxelized data unchanged: one spacing is one u);
    off_surface None -> 0.4: dfaust coherent 25.00/29.75/1.62e-9 -> 25.53/30.37/1.46e-9, human
    coherent 19.09/19.69/2.78e-9 -> 18.66/19.21/3.15e-9, independent holes unchanged (a wash on
    average; kept because a gap in an inpainted neighbour is no evidence, and because with it the
    method beats fu-nonlocal on every row below).
    Final figures (`dpcbench run methods` plus the dfaust folder as a second sequence; 10 frames,
    medium region holes seed 0, whole-frame GPSNR D1 / D2 in dB with the intrinsic peak, NSHD,
    temporal consistency in the holes (lower = steadier); defaults, version 3):
      human small, independent holes   none 7.48/25.52/6.98e-9/0.80   fu 13.40/13.82/4.81e-9/0.72
                                       temporal-graph 24.92/27.85/5.55e-10/0.23
                                       version 3 paper-like (intra_candidates=1, free, no temporal_source /
                                       dropping, link 5): fu 12.11/12.78/5.26e-9, tg 14.00/14.82/5.09e-9
      human small, coherent holes      none 8.01/26.63/6.98e-9/0.41   fu 16.25/16.68/4.17e-9/0.62
                                       temporal-graph 18.66/19.21/3.15e-9/0.50
      dfaust, independent holes        none 15.88/38.13/5.58e-9/1.35  fu 26.08/29.94/1.57e-9/1.49
                                       temporal-graph 28.81/40.43/1.02e-9/0.48
      dfaust, coherent holes           none 15.43/35.32/5.53e-9/1.20  fu 25.10/27.66/1.84e-9/2.02
                                       temporal-graph 25.53/30.37/1.46e-9/1.49
    Hole-region RMS error of temporal-graph (sqrt of the symmetric MSE, D1 / D2): human 0.67/0.53
    voxels (independent), 1.50/1.42 (coherent); dfaust 3.00/1.42 and 4.04/2.71 units (point
    spacing 3.1 units).
    Known limits: D2 against the unfilled input is hard to win (an unfilled hole costs D2 little:
    the nearest rim point of a missing point lies along the surface, so its point-to-plane error is
    small, while a fill point one voxel off the surface costs a full voxel): fu-nonlocal loses D2
    to no-fill everywhere, temporal-graph wins it on independent holes only. `temporal-copy`
    (methods.reference) beats temporal-graph on independent holes (human 26.82/29.75 dB, dfaust
    38.02/44.62 dB): when the neighbours hold the missing patch, copying it whole is hard to beat.
    """

    name = "temporal-graph"
    summary = "temporal graph inpainting (Fu, Hu, Guo ICME 2020): intra- and inter-frame source cubes on a graph"
    version = "4"  # 2: link_radius in point spacings; 3: off_surface; 4: variants and switches, free-mode fix
    uses_neighbour_frames = True
    _temporal = True

    def __init__(self, variant="tuned", cube_size=20.0, cells_per_cube=4, search_box=2.5, alpha=1.0, beta=0.5,
                 gamma=0.5, sigma=1.0, k_neighbors=None, spacing=None, known_points=None, min_known_points=16,
                 icp_iterations=10, link_radius=2.5, snap=None, agtv_weight=1.0, intra_candidates=None,
                 drop_contradicted=None, feature_fraction=None, temporal_source=None, off_surface=0.4,
                 link_cutoff=None, skip_hole_links=None, rim_centred=None, defer_unreachable=None,
                 hole_free_candidates=None, grow_source=None, new_points=None, graph_on=None):
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
    version = "2"  # 2: variants and switches, free-mode fix
    uses_neighbour_frames = False
    _temporal = False
    # not parameters: the temporal terms are off by definition, so there is no temporal evidence
    beta = 0.0
    drop_contradicted = False
    temporal_source = False
    off_surface = None
    link_cutoff = False
    skip_hole_links = False

    def __init__(self, variant="tuned", cube_size=20.0, cells_per_cube=4, alpha=1.0, gamma=0.5, sigma=1.0,
                 k_neighbors=None, spacing=None, known_points=None, min_known_points=16, icp_iterations=10,
                 snap=None, agtv_weight=1.0, intra_candidates=None, feature_fraction=None, rim_centred=None,
                 defer_unreachable=None, hole_free_candidates=None, grow_source=None, new_points=None,
                 graph_on=None):
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
