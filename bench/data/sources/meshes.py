"""Mesh sequences (OBJ, OFF, PLY with faces) sampled into point clouds by `bench.data.meshseq`: a registered
one (`MeshDataset`, e.g. "samba", found under the data folder) or any folder / glob of mesh frames.
``params``: the sampling parameters of `bench.data.meshseq.load_mesh_sequence` (points, density, bit_depth,
seed, oversampling, drop_degenerate, cache)."""

from __future__ import annotations

import inspect
import os
from dataclasses import dataclass
from pathlib import Path

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.sequences import Sequence
from dpcbench.bench.data.sources import (
    DATA_DIR_ENV,
    SequenceSource,
    data_dir_from,
    default_data_dirs,
    frame_indices,
)


@dataclass(frozen=True)
class MeshDataset:
    """A known mesh sequence read at run time: ``<data dir>/<folder>/<pattern.format(i)>``, i in
    0..count-1. ``params``: its default sampling parameters (`bench.data.meshseq.load_mesh_sequence`)."""

    name: str
    title: str
    summary: str
    source: str
    terms: str
    folder: str
    pattern: str
    count: int
    params: dict


def find_mesh_folder(info: MeshDataset, data_dir=None) -> Path | None:
    """The folder holding ``info``'s first frame: under the given data folder (or $DPCBENCH_DATA_DIR), as
    ``<dir>/<folder>``, ``<dir>/data/<folder>`` or ``<dir>`` itself, else under `default_data_dirs`."""
    roots = [r for r in [data_dir_from(data_dir)] if r is not None] + default_data_dirs()
    first = info.pattern.format(0)
    for root in roots:
        for folder in (root / info.folder, root / "data" / info.folder, root):
            if (folder / first).is_file():
                return folder
    return None


def sample_mesh_files(files: list[Path], indices, name: str, progress: bool, params: dict) -> Sequence:
    """`bench.data.meshseq.load_mesh_sequence` of ``files`` after checking the parameter names."""
    from dpcbench.bench.data.meshseq import load_mesh_sequence

    known = [n for n, p in inspect.signature(load_mesh_sequence).parameters.items()
             if p.kind is inspect.Parameter.KEYWORD_ONLY and n not in ("name", "progress")]
    unknown = sorted(set(params) - set(known))
    if unknown:
        raise UserError(f"{name}: unknown mesh sequence parameter(s) {', '.join(unknown)}; accepted: {', '.join(known)}")
    return load_mesh_sequence(files, indices, name=name, progress=progress, **params)


class MeshDatasetSource(SequenceSource):
    """A registered mesh sequence (`MeshDataset`), its frames found by `find_mesh_folder`; ``params``
    override its default sampling parameters."""

    kind = "mesh"
    cached = True

    def __init__(self, info: MeshDataset, data_dir=None):
        super().__init__(info.name)
        self.info = info
        self.data_dir = data_dir

    def load(self, frames=None, *, progress: bool = True, **params) -> Sequence:
        info = self.info
        folder = find_mesh_folder(info, self.data_dir)
        if folder is None:
            given = data_dir_from(self.data_dir)
            looked = ", ".join(str(p) for p in ([given] if given else []) + default_data_dirs())
            raise UserError(f"{info.title}: no {info.folder}/{info.pattern.format(0)} found under {looked}. It is "
                            f"published as: {info.source}. Terms: {info.terms}. Put the frames in <data dir>/{info.folder}/ "
                            f"and pass --data-dir <data dir> (or set {DATA_DIR_ENV}).")
        files = [folder / info.pattern.format(i) for i in range(info.count)]
        missing = [p.name for p in files if not p.is_file()]
        if missing:
            raise UserError(f"{info.title}: {len(missing)} of {info.count} frame files missing from {folder} "
                            f"(first: {missing[0]}); re-copy the sequence")
        indices = frame_indices(frames, len(files), info.title)
        seq = sample_mesh_files(files, indices, info.name, progress, {**info.params, **params})
        seq.meta.update({"dataset": info.name, "source": info.source, "terms": info.terms, "folder": str(folder)})
        return seq


class MeshFolderSource(SequenceSource):
    """A folder (or glob) of mesh frames, ``files`` in natural order (`bench.data.meshseq.list_mesh_files`)."""

    kind = "mesh folder"
    cached = True

    def __init__(self, path: str | os.PathLike, files: list[Path], label: str | None = None):
        p = Path(str(path))
        super().__init__(label or (p.name if p.is_dir() else p.stem))
        self.path = str(path)
        self.files = files

    def load(self, frames=None, *, progress: bool = True, **params) -> Sequence:
        indices = frame_indices(frames, len(self.files), self.path)
        seq = sample_mesh_files(self.files, indices, self.name, progress, params)
        seq.meta["source"] = self.path
        return seq
