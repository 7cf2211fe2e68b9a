"""Mesh sequences (OBJ, OFF, PLY with faces) as dynamic point clouds, with their true point motion.

Many dynamic 3D data sets are sequences of meshes (Vlasic et al.'s multi-view captures, D-FAUST
registrations, ...). ``load_mesh_sequence`` samples them into point cloud frames the way the paper's
8i data look (integer voxel coordinates, one point per occupied surface voxel) or as float samples,
and keeps the true motion of every point.

Sampling (temporally coherent, deterministic). When every frame has the same vertex count and the same
triangles (shared connectivity: vertex i is the same body point in every frame), K surface samples are
drawn once on the *reference frame* (the first file of the folder, whatever frames are selected):
faces with probability proportional to their area, then uniform barycentric coordinates on the face
(``numpy.random.default_rng(seed)``). Every frame evaluates the same (face, barycentric) samples on its
own vertices, so sample k is the same surface point in every frame. Frames whose connectivity differs
cannot share samples: each frame is then sampled on its own (``default_rng((seed, file index))``), a
warning says so, and the sequence has no motion.

Placement. One scale s and offset o for the whole sequence: x_out = s * x_mesh + o, so the motion is kept.
With ``bit_depth = b`` the union bounding box of all frames of the folder is centred in the grid
[0, 2^b - 1]^3 and s is fitted so that the reference frame occupies about ``points`` voxels (see
below); with ``bit_depth = None`` the samples stay in the mesh's units (s = 1, o = 0).

Voxelization. A sample at x_out lies in voxel round(x_out) (the voxel of integer point q is the cube
[q - 1/2, q + 1/2]^3, so integer coordinates are voxel centres, as in 8i data). A frame holds one point per
voxel that at least one of the K samples falls in. Bound: each output point q has a surface point (its
*anchor*, the sample nearest to q) with |anchor - q|_inf <= 1/2, hence within sqrt(3)/2 voxel
(Euclidean) of the surface. K = ``oversampling`` * s^2 * area(reference): with the default 8 samples
per voxel^2 of surface, a voxel whose cube the surface crosses over an area a (typical a ~ 0.7
voxel^2) is missed with probability exp(-8 a) (~0.4%); such misses are the only difference from the
exact set of voxels the surface crosses.

``points`` and ``bit_depth``. ``points`` is the target number of points of the reference frame. Float
samples: exactly ``points`` samples per frame (default 800,000). Voxelized, without ``points`` (nor
``density``): the sequence fills the grid like an 8i capture (its largest extent over all frames spans
2^b - 2 voxels) and the count is whatever the surface occupies at that scale. Voxelized with ``points``:
the number of occupied voxels grows as s^2, so s is fitted: first s = sqrt(points / sum_faces(area_f *
|n_f|_1)) (a plane with unit normal n crosses |n|_1 voxels per unit area), then up to three
corrections s <- s * sqrt(points / count). The
reference frame ends within about 1% of ``points``; other frames differ as the visible surface area
changes (their counts are reported). A target that does not fit the grid is refused (lower ``points``
or raise ``bit_depth``). ``density`` (points per unit area of the reference mesh, in its units) is an
alternative to ``points``: points = density * area(reference).

Normals: the unit normal of the face each point's anchor lies on, in that frame (right-hand rule on the
face's vertex order), written to the PLY frames as float nx ny nz (what pc_error's D2 reads).

Motion (`MeshMotion`): for frames f and g, the anchor of every point of frame f evaluated on frame g's
mesh gives its true position in frame g (scene flow = that minus its position in frame f), and the
point of frame g it lands in (its true correspondent: the anchor is one of the K samples, all of which
are voxelized in every frame, so the voxel is occupied). `metrics.temporal` uses these correspondences
instead of nearest-point links when a sequence provides them.

Bad input is refused with `UserError`: a frame without faces, non-finite vertices, degenerate faces
(repeated vertex or zero area; ``drop_degenerate=True`` drops them instead, with a warning).
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dpcbench.bench.core.errors import UserError

#: bump when the output for the same input and parameters changes (part of the cache key)
GENERATOR_VERSION = 1
MESH_SUFFIXES = (".obj", ".off", ".ply")
#: float samples per frame when neither ``points`` nor ``density`` is given (voxelized: fill the grid)
DEFAULT_POINTS = 800_000
DEFAULT_OVERSAMPLING = 8.0
#: a face is degenerate when its area is at most this times the squared bounding-box diagonal
DEGENERATE_REL_AREA = 1e-14
#: stop refining the scale when the reference frame is this close to ``points`` (relative)
SCALE_TOLERANCE = 0.005


# -- reading ------------------------------------------------------------------------------------
def ply_has_faces(path: str | os.PathLike) -> bool:
    """True when a PLY file's header declares a non-empty ``face`` element (a mesh, not a point cloud)."""
    with open(path, "rb") as fh:
        head = fh.read(65536)
    end = head.find(b"end_header")
    for line in head[: end if end >= 0 else len(head)].decode("latin-1").splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "element" and parts[1] == "face":
            return parts[2].isdigit() and int(parts[2]) > 0
    return False


def is_mesh_file(path: Path) -> bool:
    suffix = path.suffix.lower()
    if suffix in (".obj", ".off"):
        return True
    return suffix == ".ply" and ply_has_faces(path)


def list_mesh_files(source: str | os.PathLike) -> list[Path] | None:
    """The mesh frames of a folder or glob in natural order, or None when ``source`` is not a mesh
    sequence (its first candidate file is a point cloud, or it holds no OBJ/OFF/PLY file)."""
    import glob

    from dpcbench.bench.data.sequences import natural_key

    text = str(source)
    path = Path(text)
    if any(ch in text for ch in "*?["):
        files = [Path(p) for p in glob.glob(text)]
    elif path.is_dir():
        files = list(path.iterdir())
    elif path.is_file():
        files = [path]
    else:
        return None
    files = sorted((p for p in files if p.is_file() and p.suffix.lower() in MESH_SUFFIXES),
                   key=lambda p: natural_key(p.name))
    if not files or not is_mesh_file(files[0]):
        return None
    return files


def declared_vertex_count(path: Path) -> int | None:
    """How many vertices the file says it has: OBJ ``v`` lines, the OFF / PLY header count (None if unknown)."""
    suffix = path.suffix.lower()
    if suffix == ".obj":
        with open(path, "rb") as fh:
            return sum(1 for line in fh if line.startswith(b"v ") or line.startswith(b"v\t"))
    if suffix == ".ply":
        with open(path, "rb") as fh:
            head = fh.read(65536)
        for text in head[: head.find(b"end_header")].decode("latin-1").splitlines():
            parts = text.split()
            if len(parts) == 3 and parts[:2] == ["element", "vertex"] and parts[2].isdigit():
                return int(parts[2])
        return None
    if suffix == ".off":
        with open(path, "rb") as fh:
            words = []
            for line in fh:
                line = line.split(b"#")[0].strip()
                words += line.split()
                if len(words) >= 2 and words[0].upper().endswith(b"OFF") and len(words) >= 3:
                    return int(words[1]) if words[1].isdigit() else None
                if len(words) >= 1 and not words[0].upper().endswith(b"OFF"):
                    return int(words[0]) if words[0].isdigit() else None
    return None


def check_obj_faces(path: Path) -> None:
    """Refuse (UserError) an OBJ file whose face (``f``, also ``l``) indices are not vertex indices:
    positive ones must lie in 1..V (V = the file's ``v`` lines), negative (relative) ones within the
    vertices defined before the face, none may be 0 or non-numeric. Checked before pymeshlab reads the
    file: its reader does not check, and an index past the vertex list crashes the process or reads
    memory that is not the mesh."""
    total = declared_vertex_count(path) or 0
    seen = 0
    with open(path, "rb") as fh:
        for number, line in enumerate(fh, 1):
            if line.startswith((b"v ", b"v\t")):
                seen += 1
                continue
            if not line.startswith((b"f ", b"f\t", b"l ", b"l\t")):
                continue
            for token in line.split(b"#")[0].split()[1:]:
                head = token.split(b"/")[0]
                try:
                    index = int(head)
                except ValueError:
                    index = 0
                if index == 0 or index > total or -index > seen:
                    raise UserError(f"{path}: line {number}: face index {head.decode(errors='replace')!r} is not one "
                                    f"of the file's {total} vertices (1..{total}, or -1..-{seen} counted back); "
                                    "repair the mesh")


def read_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) float64, triangles (T, 3) int64) of one mesh file (OBJ, OFF, PLY), through pymeshlab:
    it keeps the file's vertex order (open3d's OBJ reader reorders vertices and drops unreferenced ones,
    which breaks vertex identity across frames) and triangulates polygons. Refuses files without faces
    and non-finite vertices (MeshLab silently drops those, so the count read is checked against the
    count the file declares)."""
    import pymeshlab

    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such file")
    if path.suffix.lower() == ".obj":
        check_obj_faces(path)
    meshes = pymeshlab.MeshSet()
    try:
        meshes.load_new_mesh(str(path))
    except Exception as err:  # pymeshlab raises its own error types on unreadable files
        raise UserError(f"{path}: cannot read the mesh ({type(err).__name__}: {err}); is it a valid OBJ/OFF/PLY "
                        "mesh?") from err
    mesh = meshes.current_mesh()
    vertices = np.asarray(mesh.vertex_matrix(), dtype=np.float64)
    triangles = np.asarray(mesh.face_matrix(), dtype=np.int64).reshape(-1, 3)
    declared = declared_vertex_count(path)
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any() or (declared is not None and declared != len(vertices)):
        count = int(bad.sum()) if bad.any() or declared is None else declared - len(vertices)
        raise UserError(f"{path}: {count} vertex/vertices have NaN, infinite or unreadable coordinates (the file "
                        f"declares {declared} vertices, {len(vertices) - int(bad.sum())} were read as finite); "
                        "repair the mesh before sampling it")
    if len(vertices) == 0:
        raise UserError(f"{path}: no vertices could be read; is it a valid OBJ/OFF/PLY mesh?")
    if len(triangles) == 0:
        raise UserError(f"{path}: the mesh has no faces, so there is no surface to sample; give a mesh with faces "
                        "(a PLY point cloud is read as a point cloud sequence instead)")
    if triangles.min() < 0 or triangles.max() >= len(vertices):
        raise UserError(f"{path}: faces refer to vertices outside 0..{len(vertices) - 1}; repair the mesh")
    return vertices, triangles


def face_areas_normals(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(areas (T,), unit normals (T, 3)) with n = (b - a) x (c - a) / |...|; zero normal for zero area."""
    a, b, c = (vertices[triangles[:, j]] for j in range(3))
    cross = np.cross(b - a, c - a)
    twice = np.linalg.norm(cross, axis=1)
    normals = np.divide(cross, twice[:, None], out=np.zeros_like(cross), where=twice[:, None] > 0)
    return 0.5 * twice, normals


def degenerate_faces(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Boolean (T,): faces with a repeated vertex index or an area <= DEGENERATE_REL_AREA * diagonal^2."""
    repeated = (triangles[:, 0] == triangles[:, 1]) | (triangles[:, 1] == triangles[:, 2]) | (
        triangles[:, 0] == triangles[:, 2])
    areas, _ = face_areas_normals(vertices, triangles)
    diagonal2 = float(((vertices.max(0) - vertices.min(0)) ** 2).sum())
    return repeated | (areas <= DEGENERATE_REL_AREA * diagonal2)


# -- sampling -------------------------------------------------------------------------------------
def sample_barycentric(areas: np.ndarray, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``count`` points uniform on the surface: faces (count,) int32 drawn with probability area / total (as
    per-face counts from one multinomial draw, so the faces come out sorted: the same distribution as
    independent draws, and later gathers run in memory order), barycentric coordinates (count, 3) uniform
    on the triangle (the unit square folded onto it)."""
    per_face = rng.multinomial(count, areas / areas.sum())
    faces = np.repeat(np.arange(len(areas), dtype=np.int32), per_face)
    r = rng.random((count, 2))
    flip = r[:, 0] + r[:, 1] > 1.0
    r[flip] = 1.0 - r[flip]
    bary = np.empty((count, 3))
    bary[:, 1:] = r
    bary[:, 0] = 1.0 - r[:, 0] - r[:, 1]
    return faces, bary


def evaluate(vertices: np.ndarray, triangles: np.ndarray, faces: np.ndarray, bary: np.ndarray,
             chunk: int = 1 << 20) -> np.ndarray:
    """Positions (K, 3) of barycentric samples: a + w1 (b - a) + w2 (c - a), (a, b, c) the vertices of
    ``triangles[faces]`` (= sum_j w_j * vertex_j since w0 + w1 + w2 = 1)."""
    a = vertices[triangles[:, 0]]
    e1 = vertices[triangles[:, 1]] - a
    e2 = vertices[triangles[:, 2]] - a
    out = np.empty((len(faces), 3))
    for s in range(0, len(faces), chunk):
        f = faces[s:s + chunk]
        w = bary[s:s + chunk]
        out[s:s + chunk] = a[f] + w[:, 1:2] * e1[f] + w[:, 2:3] * e2[f]
    return out


def voxelize_samples(positions: np.ndarray, bit_depth: int) -> tuple[np.ndarray, np.ndarray]:
    """(voxels (N, 3) int64 sorted lexicographically, anchor (N,) int64): one entry per voxel round(p) that
    a sample falls in, and for each the index of the sample nearest to the voxel centre (squared distance
    quantized to the bits left over, see below; ties: the lowest sample index). Positions must lie in
    [-1/2, 2^b - 1/2).

    One plain sort does it: each sample becomes one int64 ``voxel key | quantized distance | sample index``
    (3b + d + ceil(log2 K) <= 63 bits), so each voxel's samples come out nearest first. np.sort of int64
    is several times faster than np.argsort (vectorized sort); np.unique would need an argsort and a second
    pass for the arg-min. When the bits do not fit (huge K at 16 bits), an argsort does the same.
    """
    grid = 1 << bit_depth
    count = len(positions)
    vox = np.rint(positions).astype(np.int64)
    d2 = ((positions - vox) ** 2).sum(axis=1)  # in [0, 3/4]
    keys = (vox[:, 0] * grid + vox[:, 1]) * grid + vox[:, 2]
    del vox
    index_bits = max(1, int(count - 1).bit_length())
    d_bits = min(16, 63 - 3 * bit_depth - index_bits)
    if d_bits >= 1:
        dq = np.minimum((d2 * ((1 << d_bits) / 0.75)).astype(np.int64), (1 << d_bits) - 1)
        packed = np.sort((keys << (d_bits + index_bits)) | (dq << index_bits) | np.arange(count, dtype=np.int64))
        sorted_keys = packed >> (d_bits + index_bits)
        first = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
        anchor = packed[first] & ((1 << index_bits) - 1)
        unique_keys = sorted_keys[first]
    else:
        order = np.lexsort((np.arange(count), d2, keys))
        sorted_keys = keys[order]
        first = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
        anchor = order[first]
        unique_keys = sorted_keys[first]
    voxels = np.stack([unique_keys // (grid * grid), (unique_keys // grid) % grid, unique_keys % grid], axis=1)
    return voxels, anchor


def frame_from_samples(vertices: np.ndarray, triangles: np.ndarray, faces: np.ndarray, bary: np.ndarray,
                       bit_depth: int | None) -> dict[str, np.ndarray]:
    """One frame from surface samples on its (placed) mesh: {"points": (N, 3) uint16 voxels (or float64
    samples when bit_depth is None), "normals": (N, 3) float32 normals of the anchors' faces, "faces": (N,)
    int32 and "bary": (N, 3) the anchors}."""
    positions = evaluate(vertices, triangles, faces, bary)
    if bit_depth is None:
        points, anchor = positions, np.arange(len(faces))
    else:
        points, anchor = voxelize_samples(positions, bit_depth)
        points = points.astype(np.uint16)
    _, face_normals = face_areas_normals(vertices, triangles)
    return {"points": points, "normals": face_normals[faces[anchor]].astype(np.float32),
            "faces": faces[anchor].astype(np.int32), "bary": bary[anchor]}


# -- the sequence -----------------------------------------------------------------------------------
@dataclass
class MeshMotion:
    """True motion of the points of a mesh sequence (shared connectivity).

    vertices: per selected frame, (V, 3) vertex positions in output coordinates (x_out = s x + o).
    triangles: (T, 3) shared faces. anchors: per frame, (faces (N_f,), barycentric (N_f, 3)): the surface
    point each output point stands for. points: per frame, the (N_f, 3) output points.
    """

    vertices: list[np.ndarray]
    triangles: np.ndarray
    anchors: list[tuple[np.ndarray, np.ndarray]]
    points: list[np.ndarray]
    _trees: dict = field(default_factory=dict, repr=False)

    def positions(self, f: int, g: int) -> np.ndarray:
        """(N_f, 3): where the surface points of frame f's points are in frame g (float, output units)."""
        faces, bary = self.anchors[f]
        return evaluate(self.vertices[g], self.triangles, faces, bary)

    def flow(self, f: int, g: int) -> np.ndarray:
        """(N_f, 3) scene flow from frame f to frame g: positions(f, g) - positions(f, f)."""
        return self.positions(f, g) - self.positions(f, f)

    def indices(self, f: int, g: int) -> np.ndarray:
        """(N_f,) int: for each point of frame f, the index of the point of frame g its surface point moves
        to (the nearest point of frame g to positions(f, g): the voxel it falls in, or the same sample)."""
        from scipy.spatial import cKDTree

        if g not in self._trees:
            self._trees[g] = cKDTree(self.points[g])
        _, idx = self._trees[g].query(self.positions(f, g), k=1, workers=-1)
        return idx.astype(np.int64)

    def correspondences(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per consecutive pair (f, f + 1): (indices(f, f + 1), indices(f + 1, f)), the input
        `metrics.temporal.temporal_consistency` takes as ``correspondences``."""
        return [(self.indices(f, f + 1), self.indices(f + 1, f)) for f in range(len(self.points) - 1)]


@dataclass
class Placement:
    """x_out = scale * x_mesh + offset, and the K samples drawn on the reference frame."""

    scale: float
    offset: np.ndarray
    samples: int


def _files_fingerprint(files: list[Path]) -> list:
    """Each mesh file's name and content digest (`bench.data.file_digest`): the sampled frames' cache key."""
    from dpcbench.bench.data.file_digest import file_digests

    return file_digests(files)


def _check_params(points, density, bit_depth, oversampling) -> None:
    if points is not None and density is not None:
        raise UserError("mesh sequence: give `points` or `density`, not both")
    if points is not None and (not isinstance(points, (int, np.integer)) or isinstance(points, bool) or points < 1):
        raise UserError(f"mesh sequence: points must be a positive integer (points per frame), got {points!r}")
    if density is not None and not (isinstance(density, (int, float)) and density > 0):
        raise UserError(f"mesh sequence: density must be a positive number (points per unit area), got {density!r}")
    if bit_depth is not None and (not isinstance(bit_depth, (int, np.integer)) or not 4 <= int(bit_depth) <= 16):
        raise UserError(f"mesh sequence: bit_depth must be an integer in 4..16, or none for float samples; "
                        f"got {bit_depth!r}")
    if not (isinstance(oversampling, (int, float)) and oversampling >= 1):
        raise UserError(
            f"mesh sequence: oversampling (samples per voxel^2 of surface) must be >= 1, got {oversampling!r}")


def fit_placement(vertices0: np.ndarray, triangles: np.ndarray, areas: np.ndarray, normals: np.ndarray,
                  lo: np.ndarray, hi: np.ndarray, target: int, bit_depth: int, oversampling: float, seed: int,
                  label: str) -> Placement:
    """Scale and offset putting the sequence (bounding box lo..hi over all frames) in the centre of the
    2^b grid with the reference frame occupying about ``target`` voxels (module docstring)."""
    top = (1 << bit_depth) - 1
    extent = float((hi - lo).max())
    if extent <= 0:
        raise UserError(f"{label}: the meshes have zero extent; nothing to voxelize")
    limit = (top - 1) / extent  # s * extent <= 2^b - 2 keeps round(s x + o) inside 0..2^b - 1
    area = float(areas.sum())
    scale = float(np.sqrt(target / float((areas * np.abs(normals).sum(axis=1)).sum())))

    def placed(s):
        return s, (top / 2.0) - s * (lo + hi) / 2.0

    def too_big(s):
        max_points = int(target * (limit / s) ** 2)
        return UserError(f"{label}: {target} points at {bit_depth} bits needs {s:.4g} voxels per mesh unit, so the "
                         f"sequence would span {s * extent:.0f} voxels, more than the {top + 1}-voxel grid holds; "
                         f"ask for at most about {max_points} points, or raise bit_depth")

    for _ in range(4):
        s, o = placed(min(scale, limit))  # a trial past the grid is measured at the largest scale that fits
        count = int(np.ceil(oversampling * s * s * area))
        faces, bary = sample_barycentric(areas, count, np.random.default_rng(seed))
        voxels, _ = voxelize_samples(evaluate(vertices0 * s + o, triangles, faces, bary), bit_depth)
        scale = s * float(np.sqrt(target / len(voxels)))
        if abs(len(voxels) / target - 1.0) <= SCALE_TOLERANCE:
            scale = s
            break
        if s == limit and scale > limit:
            break  # does not fit, whatever the next trial says
    if scale > limit:
        raise too_big(scale)
    s, o = placed(scale)
    return Placement(s, o, int(np.ceil(oversampling * s * s * area)))


def _read_all(files: list[Path], name: str) -> tuple[list[tuple[np.ndarray, np.ndarray]], bool]:
    """Every mesh of ``files`` (the placement depends on the whole sequence's bounding box, so all are
    read) and whether they share connectivity (same vertex count and faces); warns when they do not."""
    meshes = [read_mesh(f) for f in files]
    v0, t0 = meshes[0]
    shared = all(len(v) == len(v0) and np.array_equal(t, t0) for v, t in meshes)
    if not shared:
        odd = next(i for i, (v, t) in enumerate(meshes) if len(v) != len(v0) or not np.array_equal(t, t0))
        warnings.warn(f"{name}: {files[odd].name} has {len(meshes[odd][0])} vertices and {len(meshes[odd][1])} faces, "
                      f"{files[0].name} {len(v0)} and {len(t0)}, or different faces: the frames do not share "
                      "connectivity, so each frame is sampled on its own and the sequence has no true point "
                      "motion (temporal consistency falls back to nearest-point links)", UserWarning, stacklevel=3)
    return meshes, shared


def _surface_triangles(files: list[Path], meshes: list, shared: bool, drop_degenerate: bool,
                       name: str) -> list[np.ndarray]:
    """The triangles each frame is sampled on. Degenerate faces (repeated vertex or zero area: no normal)
    are checked in every frame, since a face may collapse only in some: refused, or with
    ``drop_degenerate`` left out (with shared connectivity: a face degenerate in any frame, from all)."""
    degenerate = []
    for path, (v, t) in zip(files, meshes):
        bad = degenerate_faces(v, t)
        if bad.any() and not drop_degenerate:
            first = int(np.flatnonzero(bad)[0])
            raise UserError(f"{path}: {int(bad.sum())} degenerate face(s) (repeated vertex or zero area; "
                            f"first: face {first}, vertices {t[first].tolist()}); their normal is undefined. "
                            "Clean the mesh (e.g. pymeshlab meshing_remove_null_faces) "
                            "or pass drop_degenerate=true")
        degenerate.append(bad)
    if not shared:
        return [t[~bad] for (_, t), bad in zip(meshes, degenerate)]
    keep = ~np.any(degenerate, axis=0)
    if not keep.all():
        warnings.warn(f"{name}: dropped {int((~keep).sum())} face(s) degenerate in some frame", UserWarning,
                      stacklevel=3)
    return [meshes[0][1][keep]] * len(meshes)


def _placement(references: list, key: str, *, points, density, bit_depth, oversampling, seed, cache: bool,
               name: str) -> Placement:
    """The sequence's placement on the grid (cached under ``key``), fitted on the reference frame (frame 0
    of the folder) within the bounding box of the surface (vertices no face refers to left out) over
    every frame."""
    from dpcbench.bench.data.standins.cache import load_cached, store_cached

    lo = np.min([v[t].reshape(-1, 3).min(0) for v, t in references], axis=0)
    hi = np.max([v[t].reshape(-1, 3).max(0) for v, t in references], axis=0)
    stored = load_cached(key, "mesh") if cache else None
    if stored is not None:
        return Placement(float(stored["scale"]), stored["offset"], int(stored["samples"]))
    v_ref, t_ref = references[0]
    areas, _ = face_areas_normals(v_ref, t_ref)
    target = int(points if points is not None else (round(density * areas.sum()) if density is not None
                                                    else DEFAULT_POINTS))
    if target < 1:
        raise UserError(f"{name}: density {density} gives no point on a surface of area {areas.sum():.4g}")
    if bit_depth is None:
        place = Placement(1.0, np.zeros(3), target)
    elif points is None and density is None:  # fill the grid
        top = (1 << bit_depth) - 1
        extent = float((hi - lo).max())
        if extent <= 0:
            raise UserError(f"{name}: the meshes have zero extent; nothing to voxelize")
        scale = (top - 1) / extent
        place = Placement(scale, top / 2.0 - scale * (lo + hi) / 2.0,
                          int(np.ceil(oversampling * scale * scale * areas.sum())))
    else:
        _, normals = face_areas_normals(v_ref, t_ref)
        place = fit_placement(v_ref, t_ref, areas, normals, lo, hi, target, bit_depth, oversampling, seed, name)
    if cache:
        store_cached(key, "mesh", {"scale": np.array(place.scale), "offset": place.offset,
                                   "samples": np.array(place.samples)})
    return place


def _sample_frames(references: list, indices: list[int], place: Placement, identity: dict, *, shared: bool,
                   bit_depth, oversampling, seed, cache: bool, progress: bool, name: str) -> tuple[list, list, list]:
    """(point clouds, (faces, barycentric) anchors, placed vertices) of the frames ``indices``, each
    from the frame cache or sampled: with shared connectivity every frame at the same surface points
    (drawn once on the reference frame), else each frame on its own with its own seed."""
    from dpcbench.bench.data.plyio import PointCloud
    from dpcbench.bench.data.standins.cache import cache_key, load_cached, store_cached

    samples = None  # (faces, bary) on the reference frame, drawn only when a frame must be computed
    out_frames, anchors, placed_vertices = [], [], []
    iterator = indices
    if progress and len(indices) > 1:
        from dpcbench.bench.core.progress import progress_bar

        iterator = progress_bar(indices, desc=f"sampling {name}", unit="frame")
    for i in iterator:
        v, t = references[i]
        v_out = v * place.scale + place.offset
        fkey = cache_key("mesh", GENERATOR_VERSION, identity, i)
        arrays = load_cached(fkey, "mesh") if cache else None
        if arrays is None:
            if shared:
                if samples is None:
                    areas0, _ = face_areas_normals(*references[0])
                    samples = sample_barycentric(areas0, place.samples, np.random.default_rng(seed))
                faces, bary = samples
            else:
                areas_i, _ = face_areas_normals(v, t)
                count = place.samples if bit_depth is None else int(np.ceil(
                    oversampling * place.scale ** 2 * areas_i.sum()))
                faces, bary = sample_barycentric(areas_i, count, np.random.default_rng((int(seed), int(i))))
            arrays = frame_from_samples(v_out, t, faces, bary, bit_depth)
            if cache:
                store_cached(fkey, "mesh", arrays)
        normals = arrays["normals"].astype(np.float64)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)  # float32 storage: renormalize
        out_frames.append(PointCloud(arrays["points"].astype(np.float64), None, normals))
        anchors.append((arrays["faces"].astype(np.int64), arrays["bary"]))
        placed_vertices.append(v_out)
    return out_frames, anchors, placed_vertices


def load_mesh_sequence(files: list[Path], frames=None, *, name: str, points: int | None = None,
                       density: float | None = None, bit_depth: int | None = 10, seed: int = 0,
                       oversampling: float = DEFAULT_OVERSAMPLING, drop_degenerate: bool = False,
                       cache: bool = True, progress: bool = False):
    """A `bench.data.sequences.Sequence` sampled from mesh files (module docstring); ``frames``: indices into
    ``files`` (None: all). The Sequence carries ``motion`` (a `MeshMotion`) when connectivity is shared."""
    from dpcbench.bench.data.sequences import Sequence
    from dpcbench.bench.data.standins.cache import cache_key

    _check_params(points, density, bit_depth, oversampling)
    bit_depth = None if bit_depth is None else int(bit_depth)
    indices = list(range(len(files))) if frames is None else [int(i) for i in frames]
    meshes, shared = _read_all(files, name)
    triangles = _surface_triangles(files, meshes, shared, drop_degenerate, name)
    references = [(v, t) for (v, _), t in zip(meshes, triangles)]
    params = {"points": points, "density": density, "bit_depth": bit_depth, "seed": int(seed),
              "oversampling": float(oversampling), "drop_degenerate": bool(drop_degenerate)}
    identity = {"files": _files_fingerprint(files), "params": params, "shared": shared}
    place = _placement(references, cache_key("mesh", GENERATOR_VERSION, identity, -1), points=points,
                       density=density, bit_depth=bit_depth, oversampling=oversampling, seed=seed, cache=cache,
                       name=name)
    out_frames, anchors, placed_vertices = _sample_frames(
        references, indices, place, identity, shared=shared, bit_depth=bit_depth, oversampling=oversampling,
        seed=seed, cache=cache, progress=progress, name=name)
    v0, t0 = meshes[0]
    meta = {"generator": "mesh", "version": GENERATOR_VERSION, "source": str(files[0].parent),
            "params": params, "frame_indices": indices, "scale": place.scale, "offset": place.offset.tolist(),
            "samples_per_frame": place.samples, "shared_connectivity": shared,
            "vertices": len(v0), "faces": len(t0)}
    motion = MeshMotion(placed_vertices, triangles[0], anchors, [f.points for f in out_frames]) if shared else None
    seq = Sequence(name, out_frames, bit_depth, [files[i] for i in indices], meta)
    seq.motion = motion
    return seq
