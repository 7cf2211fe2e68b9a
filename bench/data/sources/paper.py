"""The paper's sequences (8i Voxelized Full Bodies, MPEG content): read from the user's local copy,
after checking that the expected files are there. These data are licensed and cannot ship with
dpcbench; `where_to_get` says where they are published and under which terms."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.sequences import Sequence, coarsened, list_frame_files, load_sequence
from dpcbench.bench.data.sources import (
    DATA_DIR_ENV,
    SequenceSource,
    data_dir_from,
    frame_indices,
    voxel_size_of,
)


@dataclass(frozen=True)
class PaperDataset:
    """One of the paper's sequences: where it is published, under which terms, which files to expect.

    Expected files: ``<folder>/<subfolder>/<pattern.format(first + i)>`` for i in 0..count-1, looked
    up under the data folder (see `find_paper_folder`). ``pattern`` None: any PLY files (naming not
    fixed by a public release we can check).
    """

    name: str
    title: str
    summary: str
    source: str
    terms: str
    folder: str
    subfolder: str | None
    pattern: str | None
    first: int
    count: int | None
    bit_depth: int | None


def find_paper_folder(info: PaperDataset, data_dir: Path) -> Path | None:
    """The folder holding the sequence's PLY frames: ``data_dir`` itself, ``data_dir/<folder>``, or
    ``data_dir/<folder>/<subfolder>`` (folder names matched case-insensitively)."""
    def child(parent: Path, name: str) -> Path | None:
        if not parent.is_dir():
            return None
        for entry in sorted(parent.iterdir()):
            if entry.is_dir() and entry.name.lower() == name.lower():
                return entry
        return None

    candidates = [data_dir]
    top = child(data_dir, info.folder)
    if top is not None:
        candidates.insert(0, top)
        if info.subfolder:
            sub = child(top, info.subfolder)
            if sub is not None:
                candidates.insert(0, sub)
    for folder in candidates:
        plys = [p for p in folder.iterdir() if p.suffix.lower() == ".ply"] if folder.is_dir() else []
        if info.pattern is None and folder != data_dir and plys:
            return folder
        if info.pattern is not None and any(p.name.startswith(info.folder) for p in plys):
            return folder
    return None


def expected_files(info: PaperDataset) -> list[str] | None:
    """The file names of the full sequence (None when the naming is not fixed)."""
    if info.pattern is None or info.count is None:
        return None
    return [info.pattern.format(info.first + i) for i in range(info.count)]


def where_to_get(info: PaperDataset) -> str:
    layout = f"{info.folder}/{info.subfolder + '/' if info.subfolder else ''}"
    example = expected_files(info)
    files = f"{example[0]} .. {example[-1]}" if example else "its PLY frames"
    return (f"{info.title} is published as: {info.source}. Terms: {info.terms}. Put a local copy so that "
            f"<data dir>/{layout} holds {files}, then pass --data-dir <data dir> (or set {DATA_DIR_ENV}).")


class PaperSource(SequenceSource):
    """A `PaperDataset` read from ``data_dir`` (or ``$DPCBENCH_DATA_DIR``). Takes no parameters."""

    kind = "paper"

    def __init__(self, info: PaperDataset, data_dir=None):
        super().__init__(info.name)
        self.info = info
        self.data_dir = data_dir

    def load(self, frames=None, *, progress: bool = True, **params) -> Sequence:
        """Read the sequence from the local copy, checking the expected files first."""
        info = self.info
        voxel_size = voxel_size_of(info.name, params)
        root = data_dir_from(self.data_dir)
        if root is None:
            raise UserError(f"{info.title}: no data folder given. {where_to_get(info)}")
        if not root.is_dir():
            raise UserError(f"{info.title}: data folder {root} does not exist. {where_to_get(info)}")
        folder = find_paper_folder(info, root)
        if folder is None:
            raise UserError(f"{info.title}: no {info.folder} PLY frames found under {root}. {where_to_get(info)}")
        expected = expected_files(info)
        if expected is None:
            files = list_frame_files(folder)
            indices = frame_indices(frames, len(files), info.title)
            chosen = [files[i] for i in indices]
        else:
            indices = frame_indices(frames, len(expected), info.title)
            chosen = [folder / expected[i] for i in indices]
            missing = [p.name for p in chosen if not p.is_file()]
            if missing:
                shown = ", ".join(missing[:3]) + (f" and {len(missing) - 3} more" if len(missing) > 3 else "")
                raise UserError(f"{info.title}: {len(missing)} of the {len(chosen)} requested frame files are missing "
                                f"from {folder}: {shown}. {where_to_get(info)}")
        seq = load_sequence(chosen, name=info.name, progress=progress)
        if info.bit_depth is not None and seq.bit_depth is not None and seq.bit_depth > info.bit_depth:
            raise UserError(f"{info.title}: {folder} holds coordinates beyond {info.bit_depth} bits; is it the "
                            f"{info.bit_depth}-bit release?")
        seq.meta.update({"dataset": info.name, "source": info.source, "terms": info.terms, "folder": str(folder)})
        return coarsened(seq, voxel_size)


def find_single_frame(info: PaperDataset, data_dir: Path) -> Path | None:
    """The one PLY frame of ``info``'s sequence under ``data_dir`` when only one is there, else None.

    Two layouts are recognised (folder and file names matched case-insensitively):
    a folder directly under ``data_dir`` (or ``data_dir`` itself) whose name contains the sequence's
    folder name and that holds exactly one PLY file named after the sequence
    (``8i_longdress_1300/longdress_vox10_1300.ply``); or the sequence's usual folder
    (`find_paper_folder`, e.g. ``longdress/Ply/``) holding exactly one PLY file. A folder with two
    or more frames is a sequence (`PaperSource`), not a single frame.
    """
    def plys(folder: Path) -> list[Path]:
        return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() == ".ply")

    key = info.folder.lower()
    if not data_dir.is_dir():
        return None
    usual = find_paper_folder(info, data_dir)
    if usual is not None and usual != data_dir:
        files = plys(usual)
        return files[0] if len(files) == 1 else None
    folders = [data_dir] + [p for p in sorted(data_dir.iterdir()) if p.is_dir()]
    for folder in folders:
        if key not in folder.name.lower():
            continue
        files = plys(folder)
        if len(files) == 1 and files[0].name.lower().startswith(key):
            return files[0]
    return None


def single_frame_rows(datasets: dict[str, PaperDataset], data_dir, labels: dict[str, str]) -> dict[str, dict]:
    """name -> the experiment's ``[[sequences]]`` entry of each of the paper's sequences found under
    ``data_dir`` as one real frame (`find_single_frame`): ``{"path": <the PLY file>, "label": "<row
    label>, one real frame"}``, in the order of ``labels`` (name -> the paper's row label). Such a
    sequence is not a sequence to load by name (its expected frames are not there): a caller lists
    it by path instead. A one-frame sequence has no neighbouring frames: the temporal method runs its
    spatial terms only, so its column there is Hu on one frame (`temporal-graph` warns and gives
    `fu-nonlocal`'s output)."""
    root = data_dir_from(data_dir)
    if root is None:
        return {}
    rows = {}
    for name, label in labels.items():
        if name not in datasets:
            continue
        found = find_single_frame(datasets[name], root)
        if found is not None:
            rows[name] = {"path": str(found), "label": f"{label}, one real frame"}
    return rows
