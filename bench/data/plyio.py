"""Reading and writing single PLY point cloud frames.

Parsing is done by `plyfile` (binary little/big endian and ASCII, any numeric property type).
Frames are written as binary little-endian PLY in the layout MPEG's tools (pc_error, TMC2) read:
``float x y z``, then optional ``uchar red green blue``, then optional ``float nx ny nz``; a frame
read from ``double`` coordinates (or integers float32 cannot hold exactly: beyond 2^24) keeps
``double x y z`` (`PointCloud.precision` = "float64"), so georeferenced data is not snapped to
float32's grid.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import plyfile

from dpcbench.bench.core.atomic import atomic_path
from dpcbench.bench.core.errors import UserError


@dataclass
class PointCloud:
    """One frame.

    points:  (N, 3) float64 coordinates (int16 or float32 from ``read_ply(..., compact=True)``).
    colors:  (N, 3) uint8 RGB, or None.
    normals: (N, 3) float64, or None.
    precision: "float64" when the coordinates were read from a type float32 cannot hold exactly
               (``double``, or integers beyond 2^24), so they are written back as ``double``;
               None: written as ``float`` (float32), as MPEG's tools expect.
    """

    points: np.ndarray
    colors: np.ndarray | None = None
    normals: np.ndarray | None = None
    precision: str | None = None

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, mask_or_index: np.ndarray) -> PointCloud:
        """The points selected by a boolean mask or index array, with their attributes."""
        return PointCloud(
            self.points[mask_or_index],
            None if self.colors is None else self.colors[mask_or_index],
            None if self.normals is None else self.normals[mask_or_index],
            self.precision,
        )


def _vertex_element(data: plyfile.PlyData, path: Path) -> plyfile.PlyElement:
    for element in data.elements:
        if element.name == "vertex":
            return element
    raise UserError(f"{path}: PLY file has no 'vertex' element; is it a point cloud?")


def _stack(vertex: plyfile.PlyElement, names: tuple[str, ...], dtype) -> np.ndarray:
    """The properties ``names`` as the columns of one (N, len(names)) array, converted column by column
    (no (N, 3) temporaries: an 800k-point frame reads in ~60 MB less peak memory)."""
    out = np.empty((len(vertex[names[0]]), len(names)), dtype=dtype)
    for column, name in enumerate(names):
        out[:, column] = vertex[name]
    return out


class _BinaryRows:
    """The rows of one element of a binary PLY file, read from the file in blocks with `np.fromfile`.

    plyfile memory-maps a binary file, and every page of the map that is read stays in the process's
    resident memory until the map is closed: a 20 MB frame with normals costs 20 MB on top of the
    arrays made from it. Reading blocks of `ROWS` rows instead bounds that to one block (~1.5 MB);
    used by ``read_ply(..., compact=True)``, whose callers measure memory.
    """

    ROWS = 1 << 16

    def __init__(self, path: Path, dtype: np.dtype, offset: int, count: int):
        self.path, self.dtype, self.offset, self.count = path, dtype, offset, count

    @classmethod
    def of(cls, path: Path, data: plyfile.PlyData, element: plyfile.PlyElement) -> _BinaryRows | None:
        """The reader of ``element``, or None for ASCII files and elements with list properties
        (variable row sizes) before or in it."""
        if data.text or element.count == 0:
            return None
        order = {"<": "<", ">": ">"}.get(data.byte_order, "=")
        offset = _header_size(path)
        for e in data.elements:
            if any(isinstance(p, plyfile.PlyListProperty) for p in e.properties) or offset is None:
                return None
            dtype = np.dtype([(p.name, order + p.val_dtype) for p in e.properties])
            if e is element:
                return cls(path, dtype, offset, e.count)
            offset += e.count * dtype.itemsize
        return None

    def blocks(self):
        """(first row, structured block) for each block of rows, in order."""
        with open(self.path, "rb") as handle:
            handle.seek(self.offset)
            for start in range(0, self.count, self.ROWS):
                want = min(self.ROWS, self.count - start)
                block = np.fromfile(handle, dtype=self.dtype, count=want)
                if len(block) < want:
                    raise UserError(f"{self.path}: the file ends after {start + len(block)} of the {self.count} "
                                    "rows its header declares; it is truncated: re-export or re-copy it")
                yield start, block

    def stack(self, names: tuple[str, ...], dtype) -> np.ndarray:
        """The properties ``names`` as the columns of one (N, len(names)) array of ``dtype``."""
        out = np.empty((self.count, len(names)), dtype=dtype)
        for start, block in self.blocks():
            for column, name in enumerate(names):
                out[start:start + len(block), column] = block[name]
        return out

    def small_integers(self, names: tuple[str, ...]) -> bool:
        """`_small_integers` of every column ``names``, block by block."""
        return all(_small_integers(block[n]) for _, block in self.blocks() for n in names)


def _header_size(path: Path) -> int | None:
    """Bytes up to and including the ``end_header`` line, None when not found in the first 64 KiB."""
    with open(path, "rb") as handle:
        head = handle.read(1 << 16)
    end = head.find(b"end_header")
    if end < 0 or head.find(b"\n", end) < 0:
        return None
    return head.find(b"\n", end) + 1


def _float_type(vertex: plyfile.PlyElement, names: tuple[str, ...], compact: bool) -> type:
    """float32 for float32 properties read compact, else float64."""
    return np.float32 if compact and all(vertex[n].dtype == np.float32 for n in names) else np.float64


def _small_integers(column: np.ndarray) -> bool:
    """Whether every value of a numeric column is an integer in int16's range (voxelized coordinates
    up to 15 bits), so that int16 holds it exactly."""
    if column.dtype.kind not in "iuf" or column.size == 0:
        return False
    if not (column.min() >= -(2**15) and column.max() < 2**15):  # False for NaN too
        return False
    return column.dtype.kind in "iu" or bool(np.equal(np.floor(column), column).all())


def _check_declared_size(data: plyfile.PlyData, path: Path) -> None:
    """Refuse a file holding more data than its header declares (plyfile reads the declared count
    and silently ignores the rest, so a wrong ``element vertex N`` would read the frame short).

    ASCII: one line per element row, so the non-empty lines after ``end_header`` must number the sum
    of the element counts. Binary with fixed-size rows (no list properties): the file size must be
    the header plus count x row size.
    """
    with open(path, "rb") as handle:
        head = handle.read(1 << 16)
    end = head.find(b"end_header")
    if end < 0 or head.find(b"\n", end) < 0:
        return
    header_size = head.find(b"\n", end) + 1
    declared = sum(e.count for e in data.elements)
    if data.text:
        body = path.read_bytes()[header_size:]
        rows = sum(1 for line in body.splitlines() if line.strip())
        if rows != declared:
            counts = ", ".join(f"{e.count} {e.name}" for e in data.elements)
            raise UserError(f"{path}: the header declares {counts} ({declared} data lines) but the file holds {rows} "
                            "data lines; fix the 'element ... N' counts in the header (or re-export the file)")
        return
    if any(isinstance(p, plyfile.PlyListProperty) for e in data.elements for p in e.properties):
        return
    expected = sum(e.count * sum(np.dtype(p.val_dtype).itemsize for p in e.properties) for e in data.elements)
    size = path.stat().st_size - header_size
    if size > expected:
        raise UserError(f"{path}: {size - expected} bytes follow the {declared} rows its header declares; the "
                        "header's 'element ... N' counts are wrong or the file is damaged: re-export it")


def read_ply(path: str | os.PathLike, *, check: bool = True, colors: bool = True, compact: bool = False) -> PointCloud:
    """Read one PLY frame. Colours are read from red/green/blue (or r/g/b), normals from nx/ny/nz.

    With ``check`` (default) a frame with zero points or non-finite coordinates is refused with a
    UserError naming the file. ``colors=False`` skips the colours (``colors`` is then None), for
    callers that only measure geometry. ``compact=True`` returns the coordinates in the narrowest
    type that holds them exactly instead of float64: int16 for voxelized frames (integers below
    2**15: a quarter of the memory), else float32 when stored as float32; normals stay float32 when
    stored so. Same values (each converts to float64 exactly), for callers that accept any numeric
    dtype (the metrics).
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such file")
    try:
        data = plyfile.PlyData.read(str(path))
        vertex = _vertex_element(data, path)
        names = {p.name for p in vertex.properties}
        if not {"x", "y", "z"} <= names:
            raise UserError(f"{path}: the vertex element has no x, y, z properties (has {sorted(names)})")
        xyz = ("x", "y", "z")
        stored = [vertex[n].dtype for n in xyz]
        rows = _BinaryRows.of(path, data, vertex) if compact else None
        if rows is not None:  # read in blocks from the file: no whole-file memory map (see _BinaryRows)
            small = rows.small_integers(xyz)
            points = rows.stack(xyz, np.int16 if small else _float_type(vertex, xyz, compact))
            normals = (rows.stack(("nx", "ny", "nz"), _float_type(vertex, ("nx", "ny", "nz"), compact))
                       if {"nx", "ny", "nz"} <= names else None)
        else:
            points = _stack(vertex, xyz, np.int16 if compact and all(_small_integers(vertex[n]) for n in xyz)
                            else _float_type(vertex, xyz, compact))
        read: np.ndarray | None = None  # the colours, None when absent or not asked for
        for rgb in (("red", "green", "blue"), ("r", "g", "b"), ("diffuse_red", "diffuse_green", "diffuse_blue")):
            if not colors:
                break
            if rows is not None and set(rgb) <= names:
                read = rows.stack(rgb, np.float64)
                if read.size and read.max() <= 1.0 and vertex[rgb[0]].dtype.kind == "f":
                    read = read * 255.0
                read = np.clip(np.rint(read), 0, 255).astype(np.uint8)  # uint8 input: the same values
                break
            if set(rgb) <= names and all(vertex[c].dtype == np.uint8 for c in rgb):
                read = _stack(vertex, rgb, np.uint8)  # already what the conversion below would give
                break
            if set(rgb) <= names:
                raw = _stack(vertex, rgb, np.float64)
                if raw.size and raw.max() <= 1.0 and vertex[rgb[0]].dtype.kind == "f":
                    raw = raw * 255.0  # float colours in [0, 1]
                read = np.clip(np.rint(raw), 0, 255).astype(np.uint8)
                break
        if rows is None:
            normals = (_stack(vertex, ("nx", "ny", "nz"), _float_type(vertex, ("nx", "ny", "nz"), compact))
                       if {"nx", "ny", "nz"} <= names else None)
    except UserError:
        raise
    except Exception as err:  # a third-party parser of the user's file: it raises many types on corrupt input
        raise UserError(
            f"{path}: cannot parse PLY ({type(err).__name__}: {err}); the file is truncated or not a "
            "valid PLY: re-export or re-copy it"
        ) from None
    _check_declared_size(data, path)
    del data, vertex  # the parsed file (~4x the points' size): free before the caller's next allocation
    cloud = PointCloud(points, read, normals, _precision(stored, points))
    if check:
        check_cloud(cloud, str(path))
    return cloud


def _precision(stored: list, points: np.ndarray) -> str | None:
    """"float64" when the stored coordinate types hold values float32 cannot: double, or integers
    beyond 2^24 (``points``: the coordinates read)."""
    if any(dtype.kind == "f" and dtype.itemsize > 4 for dtype in stored):
        return "float64"
    if any(dtype.kind in "iu" and dtype.itemsize >= 4 for dtype in stored) and points.size:
        if float(np.abs(points).max()) > 2**24:
            return "float64"
    return None


def check_cloud(cloud: PointCloud, label: str) -> None:
    """Refuse empty clouds, non-finite coordinates and coordinates beyond ``holes.regions.COORD_LIMIT``
    with a message naming ``label``."""
    if cloud.points.ndim != 2 or cloud.points.shape[1] != 3:
        raise UserError(f"{label}: coordinates must be an (N, 3) array, got shape {cloud.points.shape}")
    if len(cloud.points) == 0:
        raise UserError(f"{label}: the frame has zero points; remove it from the sequence or re-export it")
    bad = ~np.isfinite(cloud.points).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise UserError(
            f"{label}: {int(bad.sum())} point(s) have NaN or infinite coordinates (first at index {first}); "
            "clean the frame (drop those points) before using it"
        )
    from dpcbench.holes.regions import COORD_LIMIT

    top = float(np.abs(cloud.points).max())
    if top > COORD_LIMIT:
        raise UserError(f"{label}: coordinates reach {top:.3g}, beyond +-{COORD_LIMIT:g}, where squared distances "
                        "overflow and scores would be wrong; translate the frames (subtract their centre) or rescale "
                        "them")


def write_ply(path: str | os.PathLike, cloud: PointCloud | np.ndarray, *, ascii: bool = False) -> Path:
    """Write one frame as binary little-endian PLY (or ASCII with ``ascii=True``).

    Coordinates are ``float`` (float32), or ``double`` when ``cloud.precision`` is "float64" (read
    from double input). Written atomically: to a temporary file in the same folder, then renamed, so
    a reader never sees a half-written frame.
    """
    if isinstance(cloud, np.ndarray):
        cloud = PointCloud(np.asarray(cloud, dtype=np.float64))
    path = Path(path)
    n = len(cloud.points)
    coord = "<f8" if cloud.precision == "float64" else "<f4"
    fields = [("x", coord), ("y", coord), ("z", coord)]
    if cloud.colors is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    if cloud.normals is not None:
        fields += [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")]
    table = np.empty(n, dtype=fields)
    table["x"], table["y"], table["z"] = cloud.points.T
    if cloud.colors is not None:
        colors = np.asarray(cloud.colors)
        table["red"], table["green"], table["blue"] = colors.T
    if cloud.normals is not None:
        table["nx"], table["ny"], table["nz"] = cloud.normals.T
    element = plyfile.PlyElement.describe(table, "vertex")
    with atomic_path(path) as tmp:
        plyfile.PlyData([element], text=ascii, byte_order="<").write(str(tmp))
    return path
