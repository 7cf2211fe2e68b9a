"""Signed distance primitives, their smooth union, and narrow-band surface voxelization.

Distances are in voxel units. Every primitive's field is 1-Lipschitz (|f(p) - f(q)| <= |p - q|), so
a block whose centre has |f| > half its diagonal cannot hold any of the surface; the voxelizer relies
on that to evaluate the field only on a narrow band around the surface.

There is no library for vectorized analytic SDFs in our dependencies (open3d's RaycastingScene needs a
mesh, which is what we avoid building), hence these few hand-written formulas (after Inigo Quilez's
well-known distance functions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SQRT3_HALF = float(np.sqrt(3.0) / 2.0)


def _rotate_inverse(v: np.ndarray, R: np.ndarray) -> np.ndarray:
    """v @ R (= R^T applied to each row), as broadcast products: BLAS on tall (n, 3) arrays is slower
    here and much slower when other processes load the cores."""
    return v[:, :1] * R[0] + v[:, 1:2] * R[1] + v[:, 2:3] * R[2]


@dataclass
class RoundCone:
    """Capsule with different radii at its ends: points within the swept sphere from a (radius ra)
    to b (radius rb). Exact Euclidean distance (Quilez, "round cone, arbitrary")."""

    a: np.ndarray
    b: np.ndarray
    ra: float
    rb: float

    def distance(self, p: np.ndarray) -> np.ndarray:
        """p: (n, 3) -> (n,) signed distance."""
        ba = self.b - self.a
        l2 = float(ba @ ba)
        rr = self.ra - self.rb
        a2 = l2 - rr * rr
        il2 = 1.0 / l2
        pa = p - self.a
        y = pa[:, 0] * ba[0] + pa[:, 1] * ba[1] + pa[:, 2] * ba[2]  # pa . ba without a BLAS call (see _rotate_inverse)
        z = y - l2
        w = pa * l2 - np.outer(y, ba)
        x2 = np.einsum("ij,ij->i", w, w)
        y2 = y * y * l2
        z2 = z * z * l2
        k = np.sign(rr) * rr * rr * x2
        d_b = np.sqrt(x2 + z2) * il2 - self.rb
        d_a = np.sqrt(x2 + y2) * il2 - self.ra
        d_side = (np.sqrt(np.maximum(x2 * a2 * il2, 0.0)) + y * rr) * il2 - self.ra
        return np.where(np.sign(z) * a2 * z2 > k, d_b, np.where(np.sign(y) * a2 * y2 < k, d_a, d_side))

    def gradient(self, p: np.ndarray) -> np.ndarray:
        """p: (n, 3) -> (n, 3) gradient of `distance` (unit length: the field is an exact distance).

        The three branches of `distance`: beyond b, (p - b) / |p - b|; before a, (p - a) / |p - a|;
        on the side, with e = (b - a) / l, s = (p - a) . e, w = p - a - s e, rho = |w|, the side
        distance is rho cos(t) + s sin(t) - ra (cos(t) = sqrt(l^2 - (ra - rb)^2) / l,
        sin(t) = (ra - rb) / l), whose gradient is cos(t) w / rho + sin(t) e."""
        ba = self.b - self.a
        l2 = float(ba @ ba)
        rr = self.ra - self.rb
        a2 = l2 - rr * rr
        length = np.sqrt(l2)
        e = ba / length
        pa = p - self.a
        y = pa[:, 0] * ba[0] + pa[:, 1] * ba[1] + pa[:, 2] * ba[2]  # no BLAS call (see _rotate_inverse)
        z = y - l2
        s = y / length
        w = pa - np.outer(s, e)
        rho = np.sqrt(np.einsum("ij,ij->i", w, w))
        x2 = rho * rho * l2 * l2
        k = np.sign(rr) * rr * rr * x2
        cos_t, sin_t = np.sqrt(max(a2, 0.0)) / length, rr / length
        side = cos_t * w / np.maximum(rho, 1e-300)[:, None] + sin_t * e
        pb = p - self.b
        to_b = pb / np.maximum(np.linalg.norm(pb, axis=1), 1e-300)[:, None]
        to_a = pa / np.maximum(np.linalg.norm(pa, axis=1), 1e-300)[:, None]
        beyond_b = (np.sign(z) * a2 * z * z * l2 > k)[:, None]
        before_a = (np.sign(y) * a2 * y * y * l2 < k)[:, None]
        return np.where(beyond_b, to_b, np.where(before_a, to_a, side))

    def aabb(self) -> tuple[np.ndarray, np.ndarray]:
        r = max(self.ra, self.rb)
        return np.minimum(self.a, self.b) - r, np.maximum(self.a, self.b) + r


@dataclass
class Ellipsoid:
    """Ellipsoid with centre c, semi-axes radii (3,) along the columns of rotation R (3, 3).

    f(p) = min(radii) * (|q / radii| - 1), q = R^T (p - c): the exact zero set, a lower bound of the
    true distance outside and 1-Lipschitz (the map p -> q / radii stretches by at most 1 / min(radii)).
    """

    c: np.ndarray
    radii: np.ndarray
    R: np.ndarray

    def distance(self, p: np.ndarray) -> np.ndarray:
        q = _rotate_inverse(p - self.c, self.R) / self.radii
        return float(self.radii.min()) * (np.sqrt(np.einsum("ij,ij->i", q, q)) - 1.0)

    def gradient(self, p: np.ndarray) -> np.ndarray:
        """p: (n, 3) -> (n, 3) gradient of `distance`: with u = q / radii,
        grad f = min(radii) R (u / radii) / |u| (normal to the ellipsoid on its surface)."""
        u = _rotate_inverse(p - self.c, self.R) / self.radii
        norm = np.sqrt(np.einsum("ij,ij->i", u, u))
        g = float(self.radii.min()) * u / self.radii / np.maximum(norm, 1e-300)[:, None]
        return g[:, :1] * self.R[:, 0] + g[:, 1:2] * self.R[:, 1] + g[:, 2:3] * self.R[:, 2]  # g @ R^T

    def aabb(self) -> tuple[np.ndarray, np.ndarray]:
        # half extent along world axis i of a rotated ellipsoid: sqrt(sum_j (R_ij r_j)^2)
        half = np.sqrt(((self.R * self.radii) ** 2).sum(axis=1))
        return self.c - half, self.c + half


def smooth_min_weight(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """d smooth_min(a, b, k) / da = h (and d / db = 1 - h): the weight of a's gradient in the
    gradient of the smooth minimum (the terms in dh cancel: (a - b) - k (1 - 2h) = 0 where
    0 < h < 1). For k <= 0, 1 where a <= b else 0."""
    if k <= 0:
        return (a <= b).astype(np.float64)
    return np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)


def smooth_min(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth minimum (Quilez): h = clip(1/2 + (b - a) / (2k), 0, 1),
    smin = b + h (a - b) - k h (1 - h). Equals min(a, b) when |a - b| >= k; never above min(a, b)."""
    if k <= 0:
        return np.minimum(a, b)
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b + h * (a - b) - k * h * (1.0 - h)


class SmoothUnion:
    """Smooth union of primitives with blend radius k (voxels).

    ``evaluate(p, band)`` returns the field and the index of the nearest primitive. Points farther
    than ``band + k`` from a primitive's bounding box skip that primitive (it cannot change the
    union where the union is within ``band`` of zero); points near no primitive get +inf.
    """

    def __init__(self, primitives: list, k: float):
        self.primitives = primitives
        self.k = float(k)
        boxes = [prim.aabb() for prim in primitives]
        self.lo = np.array([b[0] for b in boxes])
        self.hi = np.array([b[1] for b in boxes])

    def evaluate(self, p: np.ndarray, band: float, *, gradient: bool = False):
        """p: (n, 3) float -> (field (n,), nearest primitive index (n,) int; -1 where none is near).

        With ``gradient``: (field, nearest, gradient (n, 3)), the exact gradient of the field (chain
        rule through the smooth minima, `smooth_min_weight`); NaN where no primitive is near.
        """
        n = len(p)
        field = np.full(n, np.inf)
        grad = np.full((n, 3), np.nan) if gradient else None
        nearest_d = np.full(n, np.inf)
        nearest = np.full(n, -1, dtype=np.int32)
        margin = band + self.k
        # points sorted by x: each primitive's box test only scans the slab its x-range selects
        order = np.argsort(p[:, 0], kind="stable")
        xs = p[order, 0]
        for i, prim in enumerate(self.primitives):
            lo, hi = self.lo[i] - margin, self.hi[i] + margin
            start, stop = np.searchsorted(xs, lo[0], "left"), np.searchsorted(xs, hi[0], "right")
            slab = order[start:stop]
            q = p[slab]
            inside = (q[:, 1] >= lo[1]) & (q[:, 1] <= hi[1]) & (q[:, 2] >= lo[2]) & (q[:, 2] <= hi[2])
            idx = slab[inside]
            if len(idx) == 0:
                continue
            d = prim.distance(p[idx])
            cur = field[idx]
            first = np.isinf(cur)  # no primitive near yet: the union is this primitive
            if grad is not None:  # set exactly when `gradient`
                g = prim.gradient(p[idx])
                cur_g = grad[idx]
                h = smooth_min_weight(cur[~first], d[~first], self.k)[:, None]
                cur_g[~first] = h * cur_g[~first] + (1.0 - h) * g[~first]
                cur_g[first] = g[first]
                grad[idx] = cur_g
            cur[first] = d[first]
            cur[~first] = smooth_min(cur[~first], d[~first], self.k)
            field[idx] = cur
            closer = d < nearest_d[idx]
            nearest_d[idx[closer]] = d[closer]
            nearest[idx[closer]] = i
        if gradient:
            return field, nearest, grad
        return field, nearest

    def normals(self, p: np.ndarray, band: float = 2.0) -> np.ndarray:
        """Unit outward normals (n, 3) at points p (n, 3) near the surface (within ``band``): the
        normalized gradient of the field. Points near no primitive are evaluated again with every
        primitive; where the gradient still vanishes (two blended parts facing each other exactly),
        the nearest primitive's own gradient is used."""
        _, nearest, grad = self.evaluate(p, band, gradient=True)
        far = nearest < 0
        if far.any():
            _, nearest[far], grad[far] = self.evaluate(p[far], np.inf, gradient=True)
        norm = np.linalg.norm(grad, axis=1)
        flat = ~(norm > 1e-9)
        for i in np.unique(nearest[flat]):
            sel = np.flatnonzero(flat & (nearest == i))
            grad[sel] = self.primitives[i].gradient(p[sel])
            norm[sel] = np.linalg.norm(grad[sel], axis=1)
        return grad / norm[:, None]


def surface_voxels(field: SmoothUnion, size: int, start_block: int = 32, chunk: int = 1 << 20) -> np.ndarray:
    """Integer indices (n, 3) of the voxels of the grid [0, size)^3 whose unit cube the zero level set
    crosses (its 8 corners do not all have the same sign), sorted lexicographically.

    Voxel (i, j, k) is the cube [i, i+1] x [j, j+1] x [k, k+1]. Narrow band: blocks of
    ``start_block`` voxels are kept when |f(centre)| <= half their diagonal (1-Lipschitz field), split
    into 8 children, and so on down to single voxels, whose corners are then evaluated once each.
    """
    block = min(start_block, size)
    while size % block:
        block //= 2
    n = size // block
    grid = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 3)
    children = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=np.int64)
    blocks = grid.astype(np.int64)
    while True:
        keep = []
        for s in range(0, len(blocks), chunk):
            part = blocks[s:s + chunk]
            half_diag = block * SQRT3_HALF
            d, _ = field.evaluate((part + 0.5) * block, half_diag)
            keep.append(part[np.abs(d) <= half_diag])
        blocks = np.concatenate(keep) if keep else np.empty((0, 3), np.int64)
        if block == 1 or len(blocks) == 0:
            break
        blocks = (blocks[:, None, :] * 2 + children[None]).reshape(-1, 3)
        block //= 2
    if len(blocks) == 0:
        return np.empty((0, 3), np.int64)
    # corners of the candidate voxels, each evaluated once: key = x * (size+1)^2 + y * (size+1) + z
    side = size + 1
    corners = (blocks[:, None, :] + children[None]).reshape(-1, 3)
    keys = (corners[:, 0] * side + corners[:, 1]) * side + corners[:, 2]
    unique_keys, inverse = np.unique(keys, return_inverse=True)
    unique_corners = np.stack([unique_keys // (side * side), (unique_keys // side) % side, unique_keys % side], 1)
    values = np.empty(len(unique_keys))
    for s in range(0, len(unique_keys), chunk):
        values[s:s + chunk], _ = field.evaluate(unique_corners[s:s + chunk].astype(np.float64), 2.0)
    negative = (values < 0)[inverse.reshape(-1)].reshape(-1, 8)
    crossed = negative.any(axis=1) & ~negative.all(axis=1)
    voxels = blocks[crossed]
    order = np.lexsort((voxels[:, 2], voxels[:, 1], voxels[:, 0]))
    return voxels[order]
