"""Dynamic point cloud sequences: ordered lists of frames, read from and written to PLY folders."""

from __future__ import annotations

import glob
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.plyio import PointCloud, read_ply, write_ply


def natural_key(name: str) -> list:
    """Sort key that orders embedded numbers by value: ``x_9.ply`` before ``x_10.ply``."""
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", name)]


@dataclass
class Sequence:
    """A dynamic point cloud: frames in time order.

    name:      label used in reports.
    frames:    list of PointCloud (each with (N_f, 3) points; N_f varies per frame).
    bit_depth: for voxelized data (integer coordinates in 0..2^b-1), b; None when unvoxelized.
    files:     the PLY file each frame came from, when read from disk.
    meta:      free-form provenance (generator parameters, licence notes, ...).
    motion:    the true motion of the points when the source knows it (mesh sequences with shared
               connectivity: a `bench.data.meshseq.MeshMotion`, with ``flow(f, g)``, ``indices(f, g)`` and
               ``correspondences()``); None for captured point clouds, which have no correspondence.
    """

    name: str
    frames: list[PointCloud]
    bit_depth: int | None = None
    files: list[Path] = field(default_factory=list)
    meta: dict = field(default_factory=dict)
    motion: object | None = None

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def points(self) -> list[np.ndarray]:
        """The frames as the list of (N_f, 3) arrays that methods/, holes/ and metrics/ take."""
        return [f.points for f in self.frames]

    @property
    def colors(self) -> list[np.ndarray | None]:
        return [f.colors for f in self.frames]


def list_frame_files(source: str | os.PathLike) -> list[Path]:
    """The PLY files of a sequence, in natural order. ``source`` is a folder, a glob or one file.
    Hidden and temporary files (``.*``, ``*.tmp.*``: a killed writer's leftovers) are skipped."""
    from dpcbench.bench.core.atomic import is_temporary

    text = str(source)
    path = Path(text)
    if any(ch in text for ch in "*?[") and not path.exists():
        files = [Path(p) for p in glob.glob(text) if p.lower().endswith(".ply") and not is_temporary(Path(p).name)]
        if not files:
            raise UserError(f"{text}: the pattern matches no .ply file")
    elif path.is_dir():
        files = [p for p in path.iterdir() if p.suffix.lower() == ".ply" and p.is_file() and not is_temporary(p.name)]
        if not files:
            raise UserError(f"{path}: the folder holds no .ply file; point to the folder of PLY frames")
    elif path.is_file():
        files = [path]
    else:
        raise UserError(f"{path}: no such file or folder")
    return sorted(files, key=lambda p: natural_key(p.name))


def infer_bit_depth(frames: list[PointCloud]) -> int | None:
    """b when every coordinate is a non-negative integer below 2^b (voxelized data), else None."""
    top = 0.0
    for frame in frames:
        pts = frame.points
        if pts.min() < 0 or not np.array_equal(pts, np.round(pts)):
            return None
        top = max(top, float(pts.max()))
    return max(1, int(np.ceil(np.log2(top + 1))))


def coarsen_voxels(frame: PointCloud, voxel_size: int) -> PointCloud:
    """A voxelized frame re-voxelized on a grid ``voxel_size`` times coarser, as a capture made at that
    resolution would be: each point goes to voxel ``floor(x / voxel_size)`` (so 2 turns 10-bit coordinates
    into 9-bit ones), one point per occupied voxel, in lexicographic order of the voxel; its colour is the
    rounded mean of the colours that fell into it (uint8). Normals are dropped (a mean of normals is not the
    coarser surface's normal). ``voxel_size`` 1 returns the frame as it is.

    A dozen lines by hand because open3d's voxel down-sampling keeps the points' mean position (not the
    voxel on the coarser grid) and its voxel grid counts voxels from the cloud's corner, not from 0."""
    if voxel_size == 1:
        return frame
    voxels = np.floor(np.asarray(frame.points, dtype=np.float64) / voxel_size).astype(np.int64)
    # one int64 key a voxel (21 bits an axis, coordinates of voxelized frames are below 2^21): sorting the keys
    # is sorting the voxels lexicographically, and much faster than np.unique over rows
    keys, inverse = np.unique((voxels[:, 0] << 42) | (voxels[:, 1] << 21) | voxels[:, 2], return_inverse=True)
    inverse = inverse.reshape(-1)
    mask = (1 << 21) - 1
    kept = np.stack([keys >> 42, (keys >> 21) & mask, keys & mask], axis=1).astype(np.float64)
    colors = None
    if frame.colors is not None:
        counts = np.bincount(inverse, minlength=len(kept)).astype(np.float64)
        sums = np.stack([np.bincount(inverse, weights=frame.colors[:, c].astype(np.float64), minlength=len(kept))
                         for c in range(3)], axis=1)
        colors = np.clip(np.rint(sums / counts[:, None]), 0, 255).astype(np.uint8)
    return PointCloud(kept, colors, None, frame.precision)


def coarsened(seq: Sequence, voxel_size: int) -> Sequence:
    """``seq`` with every frame through `coarsen_voxels`; UserError when its frames are not voxelized
    (non-negative integer coordinates), since a coarser grid of an unvoxelized capture is not a capture."""
    if voxel_size == 1:
        return seq
    if seq.bit_depth is None or seq.bit_depth > 21:
        raise UserError(f"{seq.name}: voxel_size={voxel_size} re-voxelizes voxelized frames (non-negative integer "
                        "coordinates below 2^21), and these are not; leave voxel_size out for this sequence")
    frames = [coarsen_voxels(frame, voxel_size) for frame in seq.frames]
    meta = {**seq.meta, "voxel_size": int(voxel_size)}
    return Sequence(seq.name, frames, infer_bit_depth(frames), seq.files, meta, None)


def load_sequence(source: str | os.PathLike | list, *, name: str | None = None, progress: bool = False,
                  colors: bool = True, compact: bool = False) -> Sequence:
    """Read every PLY frame of a folder (or glob, or single file) in natural order; a list of files is
    read in the order given. ``colors=False`` skips the colours (geometry-only callers such as
    `dpcbench score`); ``compact=True`` keeps float32 coordinates and normals as stored (see `read_ply`).

    All frames must carry the same attributes (all with colours or none, all with normals or none).
    """
    if isinstance(source, (list, tuple)):
        if not source:
            raise UserError("no frame files given")
        files = [Path(f) for f in source]
        source = files[0].parent  # label and provenance: the folder of the frames
    else:
        files = list_frame_files(source)
    iterator = files
    if progress and len(files) > 3:
        from dpcbench.bench.core.progress import progress_bar

        iterator = progress_bar(files, desc="reading frames", unit="frame")
    frames = [read_ply(f, colors=colors, compact=compact) for f in iterator]
    for attr in ("colors", "normals"):
        has = [getattr(f, attr) is not None for f in frames]
        if any(has) and not all(has):
            odd = files[has.index(not has[0])]
            raise UserError(
                f"{odd}: frames have mismatched attributes: {files[0].name} "
                f"{'has' if has[0] else 'has no'} {attr}, {odd.name} {'has' if not has[0] else 'has no'}; "
                "re-export the sequence with the same attributes in every frame"
            )
    label = name or (Path(str(source)).name if Path(str(source)).is_dir() else Path(str(source)).stem)
    return Sequence(label, frames, infer_bit_depth(frames), files, {"source": str(source)})


def save_sequence(seq: Sequence | list, out_dir: str | os.PathLike, *, prefix: str | None = None) -> list[Path]:
    """Write frames as ``<prefix>_<0000>.ply`` binary PLY files in ``out_dir``; returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    frames = seq.frames if isinstance(seq, Sequence) else [
        f if isinstance(f, PointCloud) else PointCloud(np.asarray(f, dtype=np.float64)) for f in seq
    ]
    stem = prefix or (seq.name if isinstance(seq, Sequence) else "frame")
    names = sequence_file_names(stem, len(frames))
    return [write_ply(out / name, frame) for name, frame in zip(names, frames)]


def sequence_file_names(stem: str, count: int) -> list[str]:
    """The file names `save_sequence` gives ``count`` frames: ``<stem>_0000.ply ...``."""
    width = max(4, len(str(count - 1)))
    return [f"{stem}_{i:0{width}d}.ply" for i in range(count)]


def frames_record(seq: Sequence) -> dict:
    """The holes.json keys that say which frames of the input a damage was made for: ``input_frames``
    (indices into the source, when known), ``input_files`` (the PLY file names, when read from files) and
    ``input_voxel_size`` (when they were re-voxelized coarser, `coarsened`); `check_regions_frames` compares them
    with the sequence a holes.json is later used on."""
    record: dict = {}
    indices = seq.meta.get("frame_indices")
    if indices is not None:
        record["input_frames"] = [int(i) for i in indices]
    if seq.files:
        record["input_files"] = [Path(f).name for f in seq.files]
    if seq.meta.get("voxel_size", 1) != 1:
        record["input_voxel_size"] = int(seq.meta["voxel_size"])
    return record


def check_regions_frames(holes_json: str | os.PathLike, seq: Sequence, label: str) -> None:
    """Refuse (UserError) a holes.json used on frames other than (or in another order than) those it was
    made for: the frame files of ``seq`` are matched with the record's per-frame ``file`` (the damaged
    frames) and ``input_files`` (the frames damaged), their ``voxel_size`` with ``input_voxel_size``, the embedded
    frame indices with ``input_frames``.
    Records without these keys (older ones, or hand-written) are not checked."""
    import json

    try:
        record = json.loads(Path(holes_json).read_text())
    except (OSError, ValueError):
        return
    if not isinstance(record, dict):
        return
    names = [Path(f).name for f in seq.files]
    frames = record.get("frames")
    entries = frames if isinstance(frames, list) else []
    damaged = [e.get("file") for e in entries if isinstance(e, dict)]
    for made_for in (damaged, record.get("input_files")):
        if not names or not isinstance(made_for, list) or not made_for or not all(isinstance(m, str) for m in made_for):
            continue
        same_source = made_for is record.get("input_files") and _same_path(record.get("source"), seq.meta.get("source"))
        if (same_source or set(names) & set(made_for)) and names != made_for:
            raise UserError(f"{label}: made for the frames {_names(made_for)}, but the sequence has {_names(names)}; "
                            "use the holes.json made for these frames (the same --frames, in the same order)")
    made_size, size = record.get("input_voxel_size", 1), seq.meta.get("voxel_size", 1)
    if names and made_size != size and set(names) & set(record.get("input_files") or []):
        raise UserError(f"{label}: made for these frames re-voxelized with voxel_size={made_size}, but they are read "
                        f"with voxel_size={size}; read them as the damage did (--dataset-param voxel_size={made_size}, "
                        f"or the frames `dpcbench generate FOLDER --param voxel_size={made_size}` writes)")
    indices = seq.meta.get("frame_indices")
    made = record.get("input_frames")
    if (not seq.files and indices is not None and isinstance(made, list) and seq.meta.get("generator")
            and str(record.get("source", "")).lower() == str(seq.meta.get("generator")).lower()
            and [int(i) for i in indices] != made):
        raise UserError(f"{label}: made for frames {made} of {seq.meta.get('generator')}, but these are frames "
                        f"{list(indices)}; use the holes.json made for these frames (the same --frames)")


def _same_path(a, b) -> bool:
    try:
        return a is not None and b is not None and Path(str(a)).resolve() == Path(str(b)).resolve()
    except (OSError, RuntimeError):
        return False


def _names(names: list[str]) -> str:
    return ", ".join(names[:4]) + (f" ... ({len(names)} in all)" if len(names) > 4 else "")
