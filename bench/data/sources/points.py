"""Point cloud frames on disk: a folder of PLY files (natural order), a glob, or one PLY file."""

from __future__ import annotations

import os
from pathlib import Path

from dpcbench.bench.data.sequences import Sequence, coarsened, list_frame_files, load_sequence
from dpcbench.bench.data.sources import SequenceSource, frame_indices, voxel_size_of


class PointCloudSource(SequenceSource):
    """A user's folder / glob / file of PLY frames; ``label`` names it (default: the folder's name, or
    the file's stem). Its one parameter, ``voxel_size``, re-voxelizes voxelized frames on a coarser grid
    (`bench.data.sequences.coarsened`)."""

    kind = "points"

    def __init__(self, path: str | os.PathLike, label: str | None = None):
        p = Path(str(path))
        super().__init__(label or (p.name if p.is_dir() else p.stem))
        self.path = str(path)

    def load(self, frames=None, *, progress: bool = True, **params) -> Sequence:
        voxel_size = voxel_size_of(self.path, params)
        files = list_frame_files(self.path)
        indices = frame_indices(frames, len(files), self.path)
        seq = load_sequence([files[i] for i in indices], name=self.name, progress=progress)
        seq.meta["source"] = self.path
        return coarsened(seq, voxel_size)
