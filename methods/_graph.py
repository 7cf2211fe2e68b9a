"""Graph construction and the closed-form graph-regularised solve of one cube (scipy.sparse).

Notation (paper, Eq. 5-6): a cube holds n points (rows); ``known`` marks the rows of existing
points (Omega_bar = diag(known)), the others are missing rows (Omega = diag(~known)).

Three steps of the cube pipeline live here: the spatial graph (`knn_laplacian`, on the rows or on
the source, `spatial_laplacian`), the temporal links to the aligned inter-source cubes
(`temporal_links`), and the solve of Eq. (6) (`solve_cube`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree

if TYPE_CHECKING:
    from dpcbench.holes.regions import HoleRegion


def knn_laplacian(points: np.ndarray, k: int, sigma: float) -> sp.csr_matrix:
    """Combinatorial Laplacian L = D - W (n, n) of the symmetric K-NN graph on ``points`` (n, 3).

    w_kl = exp(-||p_k - p_l||^2 / (2 sigma^2)) when l is among the k nearest neighbours of k or k
    among those of l (W = max(W_knn, W_knn^T)), else 0; D = diag(sum_l w_kl). ``k`` is clipped to
    n - 1.
    """
    n = len(points)
    k = min(int(k), n - 1)
    if k < 1:
        return sp.csr_matrix((n, n))
    dist, idx = cKDTree(points).query(points, k=k + 1)
    rows = np.repeat(np.arange(n), k)
    cols = idx[:, 1:].ravel()
    weights = np.exp(-dist[:, 1:].ravel() ** 2 / (2.0 * sigma ** 2))
    w = sp.csr_matrix((weights, (rows, cols)), shape=(n, n))
    w = w.maximum(w.T)
    degree = np.asarray(w.sum(axis=1)).ravel()
    return (sp.diags(degree) - w).tocsr()


def solve_cube(target: np.ndarray, source: np.ndarray, known: np.ndarray, laplacian: sp.spmatrix, *,
               alpha: float, gamma: float, beta: float = 0.0,
               temporal: Sequence[tuple[np.ndarray, np.ndarray]] = (), fix_known: bool = False) -> np.ndarray:
    """Minimiser c_r (n, 3) of the paper's Eq. (5), solved per coordinate as one sparse system.

        ||Omega_bar (c_r - c_t)||^2 + alpha ||Omega (c_r - c_s)||^2 + gamma tr(c_r^T L c_r)
          + beta sum_g ||D_g (c_r - W_g c_g)||^2

    target (n, 3): c_t, read on the known rows only. source (n, 3): c_s_hat, read on the missing rows
    only. known (n,) bool. laplacian (n, n). temporal: per neighbour frame g, (T_g (n, 3) = W_g c_g,
    the linked counterpart of each row, linked_g (n,) bool); D_g = diag(linked_g). Setting the
    gradient to zero gives

        (Omega_bar + alpha Omega + beta sum_g D_g + gamma L) c_r
            = Omega_bar c_t + alpha Omega c_s + beta sum_g D_g T_g,

    which is the paper's Eq. (6) when every row is linked in both frames (sum_g D_g = 2 I). The
    matrix is symmetric positive definite (positive diagonal + PSD Laplacian) and is solved with
    scipy's sparse LU (`spsolve`), all three coordinates at once; never a dense inverse.

    fix_known=True keeps the known rows at c_t (Dirichlet rows): only the missing rows u are
    solved, A_uu c_u = b_u - A_uk c_t,k.
    """
    known = np.asarray(known, dtype=bool)
    n = len(known)
    diag = np.where(known, 1.0, alpha).astype(np.float64)
    rhs = np.where(known[:, None], target, alpha * source).astype(np.float64)
    for counterpart, linked in temporal:
        linked = np.asarray(linked, dtype=bool)
        diag = diag + beta * linked
        rhs = rhs + beta * np.where(linked[:, None], counterpart, 0.0)
    system = (sp.diags(diag) + gamma * sp.csr_matrix(laplacian)).tocsc()
    if not fix_known:
        return np.asarray(spla.spsolve(system, rhs)).reshape(n, 3)
    out = np.where(known[:, None], target, 0.0).astype(np.float64)
    missing = ~known
    if not missing.any():
        return out
    system = system.tocsr()
    a_uu = system[missing][:, missing].tocsc()
    a_uk = system[missing][:, known]
    out[missing] = np.asarray(spla.spsolve(a_uu, rhs[missing] - a_uk @ target[known])).reshape(-1, 3)
    return out


def spatial_laplacian(rows: np.ndarray, source: np.ndarray, m: int, k: int, sigma: float, graph_on: str
                      ) -> sp.csr_matrix:
    """Laplacian (n, n) of the spatial graph of a cube's rows (n, 3): m known rows, then the new rows.

    graph_on="estimate": `knn_laplacian` of the rows themselves (the initial estimate
    Omega_bar c_t + Omega c_s_hat). graph_on="source" (the paper, Sec. 3.3: "we approximate the
    connectivities via the similarities in its intra-source cube"): `knn_laplacian` of c_s_hat, where a
    known row sits at its nearest point of the aligned ``source`` (S, 3) and a new row is a source
    point itself (the new rows are source points).
    """
    if graph_on == "source":
        _, nearest = cKDTree(source).query(rows[:m])
        return knn_laplacian(np.vstack([source[nearest], rows[m:]]), k, sigma)
    if graph_on != "estimate":
        raise ValueError(f"graph_on must be 'estimate' or 'source', got {graph_on!r}")
    return knn_laplacian(rows, k, sigma)


@dataclass(frozen=True)
class TemporalLinks:
    """The rows (n of them) of a cube against one aligned inter-source cube.

    counterpart (n, 3): each row's nearest aligned inter-source point (W_g c_g of Eq. 4-5).
    linked (n,): the row's temporal term is used (D_g = diag(linked)).
    contradicted (n,): that frame has data about the row and none of it is near the row.
    supported (n,): a counterpart lies within the link distance (and not in a hole of that frame).
    """

    counterpart: np.ndarray
    linked: np.ndarray
    contradicted: np.ndarray
    supported: np.ndarray


def temporal_links(rows: np.ndarray, aligned: np.ndarray, rotation: np.ndarray, translation: np.ndarray,
                   hole_regions: Sequence[HoleRegion], link_distance: float, *, link_cutoff: bool,
                   skip_hole_links: bool, off_surface: float | None) -> TemporalLinks:
    """Temporal links of the rows (n, 3) to one aligned inter-source cube ``aligned`` (S, 3).

    ``aligned = source @ rotation.T + translation``; ``hole_regions``: the hole regions of that
    frame's input (empty for an inpainted frame). With d_i the distance of row i to its nearest
    aligned point and h_i "R^T (row_i - t) lies in a hole region" (the row maps into a hole of
    that frame: its nearest point there would be the hole's rim, not the surface):

      supported_i    = d_i <= link_distance and not h_i;
      linked_i       = (d_i <= link_distance if link_cutoff else True) and not (skip_hole_links and h_i)
                       (the paper links every row to its nearest neighbour, weight 1);
      contradicted_i = not supported_i and not h_i, and, unless ``off_surface`` is None, the row lies
                       farther than off_surface * link_distance from the plane (PCA) of its 8 nearest
                       aligned points: a gap in the neighbour (an inpainted fill may have one) is no
                       evidence against a row on that neighbour's surface continued.
    """
    aligned_tree = cKDTree(aligned)
    dist, idx = aligned_tree.query(rows)
    near = dist <= link_distance
    in_hole = np.zeros(len(rows), dtype=bool)
    if hole_regions:
        back = (rows - translation) @ rotation
        for region in hole_regions:
            in_hole |= region.contains(back)
    linked = near.copy() if link_cutoff else np.ones(len(rows), dtype=bool)
    if skip_hole_links:
        linked &= ~in_hole
    near &= ~in_hole
    # contradicted: the neighbour has data there but none of it near the row. Also an inpainted
    # f-1: letting only captured data contradict was measured worse (see docs/notes-journal.md)
    contradicted = ~near & ~in_hole
    if off_surface is not None and contradicted.any() and len(aligned) >= 3:
        cand = np.flatnonzero(contradicted)
        _, nb = aligned_tree.query(rows[cand], k=min(8, len(aligned)))
        patch = aligned[nb]
        centre = patch.mean(axis=1)
        spread = patch - centre[:, None, :]
        normal = np.linalg.eigh(np.einsum("nki,nkj->nij", spread, spread))[1][:, :, 0]
        off = np.abs(np.einsum("ij,ij->i", rows[cand] - centre, normal))
        contradicted[cand] = off > off_surface * link_distance
    return TemporalLinks(aligned[idx], linked, contradicted, near)
