"""Sequence sources: where the frames of a sequence come from, behind one small interface.

A **source** is an object with a ``name`` (how reports label it), a ``kind`` and

    load(frames=None, *, progress=True, **params) -> bench.data.sequences.Sequence

``frames``: None (all; an embedded sequence: its ``default_frames``), a count N (the first N), or an
iterable of frame indices (0 = the first frame of the sequence). ``params`` are the source's own
parameters (a generator's size and motion, a mesh sampling's points and bit depth; PLY frames take only
``voxel_size``, `voxel_size_of`); a source refuses the ones it does not take with a message naming those it does.

The kinds, one file each:

- `bench.data.sources.embedded`: generated stand-ins ("human", "bunny", "cow"), cached on disk;
- `bench.data.sources.paper`:    the paper's sequences, read from the user's licensed local copy;
- `bench.data.sources.meshes`:   mesh sequences (a registered one such as "samba", or any folder of
                            OBJ/OFF/PLY meshes), sampled into point clouds by `bench.data.meshseq`;
- `bench.data.sources.points`:   a folder, glob or file of PLY point cloud frames.

`bench.data.datasets.resolve_source` is the one resolver from a name or path to a source (the
registered names live in `bench.data.datasets`); `bench.data.datasets.load_dataset` is resolve-then-load. A new
kind of source is one file here with a `SequenceSource` subclass, plus its rule in the resolver.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import ClassVar, overload

import numpy as np

from dpcbench.bench.core.errors import UserError

DATA_DIR_ENV = "DPCBENCH_DATA_DIR"


class SequenceSource:
    """Base of the sources: ``name`` labels the sequence, ``kind`` says which file defines it, ``cached``
    whether loading generates the frames into the on-disk cache (`bench.data.standins.cache`) the first time."""

    kind: ClassVar[str] = ""
    cached: ClassVar[bool] = False

    def __init__(self, name: str):
        self.name = name

    def load(self, frames=None, *, progress: bool = True, **params):
        """The frames as a `bench.data.sequences.Sequence` (see the module doc for ``frames``)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


#: the one parameter of point cloud frames read from disk (a user's folder, the paper's sequences)
VOXEL_SIZE = "voxel_size"


def voxel_size_of(what: str, params: dict) -> int:
    """The ``voxel_size`` of a source of PLY frames (`bench.data.sequences.coarsened`; 1 when not given);
    UserError for any other parameter or a value that is not an integer >= 1."""
    unknown = sorted(set(params) - {VOXEL_SIZE})
    if unknown:
        raise UserError(f"{what}: unknown parameter(s) {', '.join(unknown)} of PLY frames; they take only "
                        f"{VOXEL_SIZE} (an integer >= 1: re-voxelize on a grid that many voxels coarser)")
    size = params.get(VOXEL_SIZE, 1)
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
        raise UserError(f"{what}: {VOXEL_SIZE} must be an integer >= 1 (2 makes 10-bit frames 9-bit), got {size!r}")
    return int(size)


@overload
def frame_indices(frames: int | np.integer | Iterable[int], available: int | None, label: str) -> list[int]: ...
@overload
def frame_indices(frames: None, available: int, label: str) -> list[int]: ...
@overload
def frame_indices(frames: None, available: None, label: str) -> None: ...
def frame_indices(frames: int | np.integer | Iterable[int] | None, available: int | None,
                  label: str) -> list[int] | None:
    """frames (None | count | iterable of indices) -> sorted-as-given list of indices (None = all)."""
    if frames is None:
        return None if available is None else list(range(available))
    if isinstance(frames, (int, np.integer)):
        if frames < 1:
            raise UserError(f"{label}: frames must be at least 1, got {frames}")
        indices = list(range(int(frames)))
    else:
        indices = [int(i) for i in frames]
        if not indices:
            raise UserError(f"{label}: the frame list is empty")
        if min(indices) < 0:
            raise UserError(f"{label}: frame indices must be >= 0, got {min(indices)}")
    if available is not None and max(indices) >= available:
        raise UserError(f"{label}: frame {max(indices)} requested but the sequence has {available} frames "
                        f"(0..{available - 1}); ask for fewer frames")
    return indices


def data_dir_from(data_dir: str | os.PathLike | None) -> Path | None:
    """The data folder: the argument, else ``$DPCBENCH_DATA_DIR``, else None."""
    value = data_dir if data_dir not in (None, "") else os.environ.get(DATA_DIR_ENV)
    return Path(value).expanduser() if value else None


def default_data_dirs() -> list[Path]:
    """Where data is looked for when no folder is given: ``../shared/data`` beside the repository."""
    repo = Path(__file__).resolve().parents[3]
    return [repo.parent / "shared" / "data"]
