"""`lozes-pde`: hole filling by the graph p-Laplacian, after Lozes, Elmoataz and Lezoray.

References: F. Lozes, A. Elmoataz, O. Lezoray, "PDE-based graph signal processing for 3-D color
point clouds", IEEE Signal Processing Magazine 32(4), 2015; "Partial difference operators on
weighted graphs for image processing on surfaces and point clouds", IEEE TIP 23(9), 2014; and the
operators of Elmoataz, Lezoray, Bougleux, IEEE TIP 17(7), 2008.

From the papers:
  * the point cloud is a weighted graph G = (V, E, w); a signal f: V -> R^m lives on its vertices;
  * weighted gradient norm  |grad_w f|(u) = sqrt( sum_{v~u} w_uv ||f(v) - f(u)||^2 );
  * isotropic graph p-Laplacian
        Delta_{w,p} f(u) = 1/2 sum_{v~u} gamma_uv (f(v) - f(u)),
        gamma_uv = w_uv ( |grad_w f|(u)^(p-2) + |grad_w f|(v)^(p-2) );
  * inpainting = p-Laplacian regularization with the data term only on the known vertices: the
    known vertices are fixed, the unknown ones solve Delta_{w,p} f = 0, reached by the Gauss-Jacobi
    fixed point  f(u) <- sum_v gamma_uv f(v) / sum_v gamma_uv  (with gamma re-evaluated each step);
  * p = 2 (linear, Tikhonov / harmonic) and p = 1 (total variation; |grad| regularized as
    sqrt(|grad|^2 + eps^2) so gamma stays finite);
  * geometric inpainting: the signal is the vertex coordinates, f(u) = x_u in R^3.

Our design (the papers leave it open or work on other data):
  * Seeding (where the new vertices come from). For each hole region R: the *ring* is the known
    points within ``ring_spacings * s`` of R (s = point spacing of the frame). The plane of the
    ring's PCA (centroid c, normal = least-variance axis) is covered by a square grid of step s
    (s from `sampling_step`: the frame's areal density)
    over the disc of radius ``bounding_radius(R) + ring width`` around R's projected centre; a
    grid node is a new vertex when its plane point lies within R grown by half the ring width and
    its 2-D projection is farther than ``gap_spacings * s`` from every projected ring point (the
    hole's footprint). So new points are seeded at the data's sampling density, lifted onto the
    ring's plane, and the p-Laplacian moves them from there.
  * Graph: K-NN (``k_neighbours``) over ring + new vertices, symmetrized (w = max(w_uv, w_vu)),
    weights w_uv = exp(-||x_u - x_v||^2 / (2 (sigma_spacings * s)^2)) computed once on the seeded
    positions (the graph is fixed during the evolution, as in the papers).
  * Solver. ``solver="jacobi"``: the papers' Gauss-Jacobi fixed point above, literally.
    ``solver="direct"`` (default): the same fixed point reached faster: with gamma frozen, the
    Jacobi fixed point is the sparse linear system
        sum_v gamma_uv (x_u - x_v) = 0 for unknown u  (known x_v fixed),
    solved exactly (scipy.sparse.linalg.splu); for p = 2 gamma = 2 w is constant so one solve is
    the converged result; for p = 1 gamma is re-evaluated and the system re-solved (lagged
    diffusivity) until converged. Both stop when the largest move of a vertex in one step is below
    ``tolerance * s`` or after ``max_iterations`` steps (then a RuntimeWarning says so).
    Why "direct" is the default: Jacobi on a hole d spacings across needs O(d^2) sweeps; measured
    in `tests/test_baselines.py` (both reach the same points on the planar hole).
  * New vertices in a graph component with no known vertex (nothing to anchor them) are dropped.

What to expect (measured on dfaust_50004_punching, medium holes; a one-off script, not kept): with
the rim fixed and no data term inside the hole, p = 2 gives a harmonic, nearly flat patch spanning
the rim (the "planar structures" the ICME paper notes for Lozes), so on a curved body part it sits
inside the surface (mean distance of the new points to the truth 3.8 units in a knee hole, point
spacing 2.8). p = 1 (graph TV on the coordinates) favours piecewise-constant coordinates, so the new
points bunch together (median nearest-neighbour distance 0.86 against 1.85 for p = 2 in the same
hole); p = 2 is the default.
  * Regions are filled independently; new vertices that fall inside an earlier region of the same
    frame are dropped, so overlapping regions are filled once.
  * ``regions=None`` (blind): regions from `holes.detection.detect_holes`, when it is available.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._geometry import detect_regions, sampling_step  # sampling_step re-exported
from dpcbench.methods.base import PerFrameMethod, Regions
from dpcbench.metrics.errors import UserError


class LozesPDE(PerFrameMethod):
    """Frame-by-frame hole filling by the graph p-Laplacian on the point coordinates (see module
    docstring for what comes from Lozes et al. and what is our design)."""

    name = "lozes-pde"
    summary = "graph p-Laplacian (p=2 or 1) evolution of seeded hole points, frame by frame (Lozes et al. 2014/2015)"
    version = "1"
    detects_holes = True

    def __init__(self, p: float = 2.0, k_neighbours: int = 10, sigma_spacings: float = 1.0,
                 ring_spacings: float = 3.0, gap_spacings: float = 0.8, epsilon: float = 1e-3,
                 tolerance: float = 1e-4, max_iterations: int = 500, solver: str = "direct",
                 max_new_points: int = 200_000):
        self.p = p
        self.k_neighbours = k_neighbours
        self.sigma_spacings = sigma_spacings
        self.ring_spacings = ring_spacings
        self.gap_spacings = gap_spacings
        self.epsilon = epsilon
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.solver = solver
        self.max_new_points = max_new_points

    # -- parameters -----------------------------------------------------------------------------
    def _validate_params(self) -> None:
        if self.p not in (1, 2):
            raise UserError(f"lozes-pde: p must be 1 (total variation) or 2 (Laplacian), got {self.p!r}")
        if self.solver not in ("direct", "jacobi"):
            raise UserError(f"lozes-pde: solver must be 'direct' or 'jacobi', got {self.solver!r}")
        if int(self.k_neighbours) < 2:
            raise UserError(f"lozes-pde: k_neighbours must be >= 2, got {self.k_neighbours}")
        for key in ("sigma_spacings", "ring_spacings", "gap_spacings", "epsilon", "tolerance"):
            if not getattr(self, key) > 0:
                raise UserError(f"lozes-pde: {key} must be > 0, got {getattr(self, key)!r}")
        if int(self.max_iterations) < 1:
            raise UserError(f"lozes-pde: max_iterations must be >= 1, got {self.max_iterations}")
        if int(self.max_new_points) < 1:
            raise UserError(f"lozes-pde: max_new_points must be >= 1, got {self.max_new_points}")

    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        self._validate_params()
        if regions is None:
            frames, _ = self._check_inputs(frames, None)
            regions = detect_regions(frames, self.name)
        return super().inpaint(frames, regions)

    # -- one frame --------------------------------------------------------------------------------
    def inpaint_frame(self, points: np.ndarray, regions: Sequence[HoleRegion] | None) -> np.ndarray:
        if not regions:  # `inpaint` detects the regions when none are given: nothing to fill here
            return points.copy()
        spacing = sampling_step(points)
        new_parts = []
        for k, region in enumerate(regions):
            seeds, ring = self.seed_hole(points, region, spacing)
            if len(seeds) == 0:
                continue
            filled = self.evolve(ring, seeds, spacing)
            for earlier in regions[:k]:
                filled = filled[~earlier.contains(filled)]
            new_parts.append(filled)
        return np.concatenate([points, *new_parts], axis=0) if new_parts else points.copy()

    def seed_hole(self, points, region, spacing) -> tuple[np.ndarray, np.ndarray]:
        """(seeds (S, 3) on the ring's plane inside the hole's footprint, ring (K, 3) known points)."""
        ring_width = self.ring_spacings * spacing
        ring = points[region.contains(points, margin=ring_width)]
        if len(ring) < 3:  # no surface around this region: nothing to fill from
            return np.empty((0, 3)), ring
        centroid = ring.mean(axis=0)
        _, _, axes = np.linalg.svd(ring - centroid, full_matrices=False)
        tangent = axes[:2]  # (2, 3) rows: the two largest-variance directions
        ring_2d = (ring - centroid) @ tangent.T
        centre_2d = (region.center - centroid) @ tangent.T
        extent = region.bounding_radius + ring_width
        steps = int(np.ceil(extent / spacing))
        if (2 * steps + 1) ** 2 > 4 * int(self.max_new_points):
            raise UserError(
                f"lozes-pde: a hole region of radius {region.bounding_radius:.4g} is {extent / spacing:.0f} point "
                f"spacings across; seeding it would exceed max_new_points={self.max_new_points}. Use smaller "
                "regions or raise max_new_points")
        offsets = np.arange(-steps, steps + 1) * spacing
        grid_2d = np.stack(np.meshgrid(offsets, offsets, indexing="ij"), axis=-1).reshape(-1, 2) + centre_2d
        grid_2d = grid_2d[np.linalg.norm(grid_2d - centre_2d, axis=1) <= extent]
        grid_3d = centroid + grid_2d @ tangent
        keep = region.contains(grid_3d, margin=0.5 * ring_width)
        gap, _ = cKDTree(ring_2d).query(grid_2d[keep], k=1)
        seeds = grid_3d[keep][gap > self.gap_spacings * spacing]
        if len(seeds) > int(self.max_new_points):
            raise UserError(f"lozes-pde: {len(seeds)} points to seed in one hole exceed max_new_points="
                             f"{self.max_new_points}; use smaller regions or raise max_new_points")
        return seeds, ring

    def evolve(self, known: np.ndarray, seeds: np.ndarray, spacing: float) -> np.ndarray:
        """Positions (S', 3) of the seeds after the p-Laplacian evolution with ``known`` fixed."""
        positions = np.concatenate([known, seeds], axis=0)
        n_known = len(known)
        weights = self._graph(positions, spacing)
        # keep only the seeds that are connected to some known vertex
        _, labels = connected_components(weights, directed=False)
        anchored = np.isin(labels, np.unique(labels[:n_known]))
        if not anchored[n_known:].all():
            positions, weights = positions[anchored], weights[anchored][:, anchored]
        unknown = np.arange(n_known, len(positions))
        if len(unknown) == 0:
            return np.empty((0, 3))
        edges = weights.tocoo()
        rows, cols, edge_w = edges.row, edges.col, edges.data

        tolerance = self.tolerance * spacing
        eps = self.epsilon * spacing
        linear = self.p == 2
        for _ in range(int(self.max_iterations)):
            gamma = edge_w * 2.0 if linear else self._gamma(positions, rows, cols, edge_w, eps)
            gamma_matrix = sp.csr_matrix((gamma, (rows, cols)), shape=weights.shape)
            if self.solver == "jacobi":
                updated = (gamma_matrix[unknown] @ positions) / np.asarray(gamma_matrix[unknown].sum(axis=1))
            else:
                updated = _solve_dirichlet(gamma_matrix, positions, n_known)
            move = float(np.abs(updated - positions[unknown]).max())
            positions[unknown] = updated
            if move < tolerance or (linear and self.solver == "direct"):
                return positions[unknown]
        warnings.warn(f"lozes-pde: did not converge in {self.max_iterations} iterations (last move "
                      f"{move:.3g}, tolerance {tolerance:.3g}); raise max_iterations", RuntimeWarning, stacklevel=3)
        return positions[unknown]

    def _graph(self, positions: np.ndarray, spacing: float) -> sp.csr_matrix:
        """Symmetric K-NN weight matrix, w_uv = exp(-||x_u - x_v||^2 / (2 sigma^2))."""
        k = min(int(self.k_neighbours), len(positions) - 1)
        dist, idx = cKDTree(positions).query(positions, k=k + 1, workers=-1)
        sigma = self.sigma_spacings * spacing
        rows = np.repeat(np.arange(len(positions)), k)
        w = np.exp(-dist[:, 1:].ravel() ** 2 / (2.0 * sigma ** 2))
        directed = sp.csr_matrix((w, (rows, idx[:, 1:].ravel())), shape=(len(positions),) * 2)
        return directed.maximum(directed.T).tocsr()

    def _gamma(self, positions, rows, cols, edge_w, eps) -> np.ndarray:
        """gamma_uv = w_uv (g_u^(p-2) + g_v^(p-2)), g_u = sqrt(sum_v w_uv ||x_v - x_u||^2 + eps^2)."""
        diff2 = ((positions[cols] - positions[rows]) ** 2).sum(axis=1)
        grad = np.sqrt(np.bincount(rows, weights=edge_w * diff2, minlength=len(positions)) + eps ** 2)
        power = grad ** (self.p - 2.0)
        return edge_w * (power[rows] + power[cols])


def _solve_dirichlet(gamma: sp.csr_matrix, positions: np.ndarray, n_known: int) -> np.ndarray:
    """Unknown rows (index >= n_known) of the solution of  sum_v gamma_uv (x_u - x_v) = 0  for
    every unknown u, with the known rows of ``positions`` fixed: (D_uu - G_uu) x_u = G_uk x_k."""
    g_uu = gamma[n_known:, n_known:]
    g_uk = gamma[n_known:, :n_known]
    degree = np.asarray(gamma[n_known:].sum(axis=1)).ravel()
    system = (sp.diags(degree) - g_uu).tocsc()
    rhs = g_uk @ positions[:n_known]
    return splu(system).solve(np.ascontiguousarray(rhs))
