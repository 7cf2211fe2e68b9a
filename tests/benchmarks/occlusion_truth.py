"""Occlusion generator against exact visibility: which operator (HPR or the z-buffer) removes the points
that a rig truly cannot see, on meshes where the surface is known.

    python tests/benchmarks/occlusion_truth.py                       # bunny, samba, two spheres; 2 rigs
    python tests/benchmarks/occlusion_truth.py --cases bunny --voxels 600 --rigs stage

Per case the mesh is scaled into a 10-bit grid (largest extent ``--voxels`` voxels), sampled uniformly
(8 samples per voxel^2, as `bench.data.meshseq` does) and voxelized: one point per occupied voxel, anchored
to the sample nearest its centre (`meshseq.voxelize_samples`); ``--float`` keeps the samples instead.

Exact visibility (`holes.occlusion.raycast_visible_mask`, open3d's RaycastingScene on the mesh): camera c
sees point q (anchor p on the mesh, face normal n) when the first hit of the ray c -> p lies within ``--tolerance`` voxels of
|p - c|, and ``|n . v| >= min_cos`` with v = (c - p) / |c - p| (the generator's grazing test, with the
mesh's normal instead of a PCA one). Exact removed set = points seen by no camera, after the same
``seen_within`` cover rule as the generator (`unseen_after_cover`, 1.5 point spacings).

Prints, per case and rig: points, exact removed count, and for each operator its removed count,
precision = |R & E| / |R|, recall = |R & E| / |E|, F1 and IoU = |R & E| / |R | E| against the exact set
E, plus the CPU seconds of its `occluded_mask`; after the bar, the same against the exact set graded with
the PCA normals the operators use (the grazing test then agrees by construction, so what is left is the
visibility operator's own error).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

SAMPLES_PER_VOXEL2 = 8.0


def two_spheres() -> tuple[np.ndarray, np.ndarray]:
    """A sphere of radius 1 and one of radius 0.6 beside it (gap 0.25) along x: each shadows the other."""
    import open3d as o3d

    parts = []
    for radius, x in ((1.0, 0.0), (0.6, 1.85)):
        m = o3d.geometry.TriangleMesh.create_sphere(radius=radius, resolution=120)
        m.translate((x, 0.0, 0.0))
        parts.append((np.asarray(m.vertices), np.asarray(m.triangles)))
    v = np.vstack([parts[0][0], parts[1][0]])
    t = np.vstack([parts[0][1], parts[1][1] + len(parts[0][0])])
    return v, t


def load_case(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) float64, triangles (T, 3) int64) of a test mesh, y up."""
    if name == "bunny":
        from dpcbench.bench.data.standins.bunny import rest_mesh

        v, t, _ = rest_mesh()
        return v, t
    if name == "samba":
        from dpcbench.bench.data.meshseq import read_mesh

        v, t = read_mesh("/work/shared/data/mit_samba/samba_0000.obj")
        return np.asarray(v, dtype=np.float64), np.asarray(t, dtype=np.int64)
    if name == "spheres":
        return two_spheres()
    raise SystemExit(f"unknown case {name!r}: use bunny, samba or spheres")


def sample_frame(vertices, triangles, voxels: float, voxelize: bool, seed: int = 0):
    """(points (N, 3), anchors (N, 3) on the mesh, anchor face normals (N, 3)) in voxel units."""
    from dpcbench.bench.data.meshseq import evaluate, face_areas_normals, sample_barycentric, voxelize_samples

    lo, hi = vertices.min(0), vertices.max(0)
    scale = voxels / float((hi - lo).max())
    v = (vertices - lo) * scale + 8.0  # inside [0, 2^10) with a margin
    if v.max() >= 1023:
        raise SystemExit(f"--voxels {voxels} does not fit a 10-bit grid")
    areas, face_normals = face_areas_normals(v, triangles)
    rng = np.random.default_rng(seed)
    count = int(SAMPLES_PER_VOXEL2 * areas.sum()) if voxelize else int(areas.sum())
    faces, bary = sample_barycentric(areas, count, rng)
    positions = evaluate(v, triangles, faces, bary)
    if voxelize:
        points, anchor = voxelize_samples(positions, 10)
        points = points.astype(np.float64)
    else:
        points, anchor = positions, np.arange(len(positions))
    return points, positions[anchor], face_normals[faces[anchor]], v


def scores(removed: np.ndarray, exact: np.ndarray) -> tuple[float, float, float, float]:
    """(precision, recall, F1, IoU) of ``removed`` against ``exact`` (1.0 where both are empty)."""
    both = int((removed & exact).sum())
    r, e, union = int(removed.sum()), int(exact.sum()), int((removed | exact).sum())
    precision = both / r if r else 1.0
    recall = both / e if e else 1.0
    f1 = 2 * both / (r + e) if r + e else 1.0
    return precision, recall, f1, (both / union if union else 1.0)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", default="bunny,samba,spheres")
    parser.add_argument("--rigs", default="stage,sphere8")
    parser.add_argument("--voxels", type=float, default=500.0, help="largest extent in voxels (10-bit grid)")
    parser.add_argument("--float", dest="voxelize", action="store_false", help="float samples, not voxels")
    parser.add_argument("--tolerance", type=float, default=0.01, help="ray hit tolerance in voxels")
    parser.add_argument("--operators", default="hpr,zbuffer")
    parser.add_argument("--depth-tolerance", type=float, default=None, help="z-buffer's, in point spacings")
    parser.add_argument("--splat", type=float, default=None, help="z-buffer's splat radius in point spacings")
    args = parser.parse_args(argv)
    from dpcbench.holes.geometry import estimate_normals, point_spacing
    from dpcbench.holes.occlusion import OcclusionHoles, raycast_visible_mask, unseen_after_cover

    rigs = {"stage": {"rig": "stage"}, "sphere8": {"rig": "sphere", "count": 8},
            "sphere20": {"rig": "sphere", "count": 20}}
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"{'voxelized 10-bit' if args.voxelize else 'float samples'}, extent {args.voxels:g} voxels")
    print(f"{'case':8s} {'rig':8s} {'points':>7s} {'exact':>6s} {'op':7s} {'removed':>7s} {'prec':>6s} "
          f"{'recall':>6s} {'F1':>6s} {'IoU':>6s} {'cpu s':>6s} | {'exPCA':>6s} {'prec':>6s} {'recall':>6s} "
          f"{'F1':>6s} {'IoU':>6s}")
    for case in args.cases.split(","):
        vertices, triangles = load_case(case)
        points, anchors, normals, mesh_v = sample_frame(vertices, triangles, args.voxels, args.voxelize)
        spacing = point_spacing(points)
        pca = estimate_normals(points, OcclusionHoles().normal_k)
        for rig in args.rigs.split(","):
            gen = OcclusionHoles(**rigs[rig])
            cams = gen._cameras(points, 0.0)
            seen = raycast_visible_mask(mesh_v, triangles, anchors, normals, cams, gen.min_cos, args.tolerance)
            exact = unseen_after_cover(points, seen, gen.seen_within * spacing)
            # the same rays, graded with the operators' PCA normals: what the visibility operator alone gets wrong
            seen_pca = raycast_visible_mask(mesh_v, triangles, anchors, pca, cams, gen.min_cos, args.tolerance)
            exact_pca = unseen_after_cover(points, seen_pca, gen.seen_within * spacing)
            for op in args.operators.split(","):
                t0 = time.process_time()
                extra = {} if op == "hpr" else {k: v for k, v in (("depth_tolerance", args.depth_tolerance),
                                                                 ("splat", args.splat)) if v is not None}
                removed = OcclusionHoles(visibility=op, **rigs[rig], **extra).occluded_mask(points, 0.0, spacing)
                cpu = time.process_time() - t0
                p, r, f1, iou = scores(removed, exact)
                p2, r2, f2, iou2 = scores(removed, exact_pca)
                print(f"{case:8s} {rig:8s} {len(points):7d} {int(exact.sum()):6d} {op:7s} {int(removed.sum()):7d} "
                      f"{p:6.3f} {r:6.3f} {f1:6.3f} {iou:6.3f} {cpu:6.2f} | {int(exact_pca.sum()):6d} "
                      f"{p2:6.3f} {r2:6.3f} {f2:6.3f} {iou2:6.3f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
