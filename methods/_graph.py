"""Graph construction and the closed-form graph-regularised solve of one cube (scipy.sparse).

Notation (paper, Eq. 5-6): a cube holds n points (rows); ``known`` marks the rows of existing
points (Omega_bar = diag(known)), the others are missing rows (Omega = diag(~known)).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree


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
               temporal: list[tuple[np.ndarray, np.ndarray]] = (), fix_known: bool = False) -> np.ndarray:
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
