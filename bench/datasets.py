"""The dataset registry: embedded stand-in sequences, the paper's sequences, and user folders.

``load_dataset(name_or_path, frames=None, data_dir=None, **params) -> Sequence``:

- an embedded name (``EMBEDDED``: "human", "bunny") generates the frames (deterministic for the
  same parameters; cached on disk, see `bench.standins.cache`);
- a paper sequence name (``PAPER``: longdress, loot, redandblack, soldier, ulliwegner) reads the
  user's local copy from ``data_dir`` or ``$DPCBENCH_DATA_DIR``, after checking that the expected
  files are there; these data are licensed and cannot ship with dpcbench;
- a mesh sequence name (``MESHES``: "samba") samples the mesh frames found under ``data_dir``,
  ``$DPCBENCH_DATA_DIR`` or the repository's ``../shared/data`` (see `bench.meshseq`);
- anything else is a path: a folder of PLY frames, a glob, or one PLY file; a folder (or glob) of mesh
  frames (OBJ, OFF, PLY with faces) is sampled into point clouds by `bench.meshseq` and takes its
  parameters (points, density, bit_depth, seed, oversampling, drop_degenerate, cache).

``frames``: None (embedded: ``default_frames``; files: all), a count N (the first N), or an iterable
of frame indices (0 = the first frame of the sequence).

Every user mistake (unknown name, missing data, bad parameter) raises `bench.errors.UserError` with
a message that says what to do.
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.errors import UserError, warn
from bench.paper_facts import PAPER_SEQUENCES
from bench.params import parse_param_value, parse_params  # noqa: F401  (the one --param parser)
from bench.plyio import PointCloud
from bench.sequences import Sequence, list_frame_files, load_sequence

DATA_DIR_ENV = "DPCBENCH_DATA_DIR"


@dataclass(frozen=True)
class EmbeddedDataset:
    """A generated sequence: ``module.generate_frame(index, **params) -> (points, colours, normals)``."""

    name: str
    description: str
    module: str  # import path of the generator module (GENERATOR_VERSION, generate_frame)
    default_frames: int = 10

    def generator(self):
        import importlib

        return importlib.import_module(self.module)

    def parameters(self) -> dict:
        """Parameter name -> default value of the generator (besides the frame index)."""
        sig = inspect.signature(self.generator().generate_frame)
        return {n: p.default for n, p in sig.parameters.items() if p.kind is inspect.Parameter.KEYWORD_ONLY}


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


EMBEDDED: dict[str, EmbeddedDataset] = {
    "human": EmbeddedDataset(
        "human",
        "procedural human figure in motion (walk/dance/wave), smooth-blended body parts, surface voxelized "
        "like 8i data (integer coordinates at bit_depth, one point per surface voxel), with colours; "
        "size=tiny ~24k, small ~96k, default ~575k points per frame",
        "bench.standins.human",
    ),
    "bunny": EmbeddedDataset(
        "bunny",
        "the Stanford bunny scan (pymeshlab sample mesh) bent, twisted and bumped non-rigidly while turning, "
        "resampled every frame and voxelized at bit_depth (or float samples with bit_depth=None); "
        "size=tiny ~19k, small ~97k, default ~630k points per frame",
        "bench.standins.bunny",
    ),
}

_8I_SUMMARY = "8i Voxelized Full Bodies (JPEG Pleno / MPEG), 10-bit, 300 frames; non-commercial research use"
_8I_SOURCE = ("8i Voxelized Full Bodies (8iVFB v2), E. d'Eon, B. Harrison, T. Myers, P. A. Chou, ISO/IEC JTC1/SC29 "
              "WG1 m74006 / WG11 m40059, 2017; download from the JPEG Pleno database "
              "http://plenodb.jpeg.org/pc/8ilabs (also in the MPEG content repository)")
_8I_TERMS = ("free of charge for non-commercial research and standardization use under 8i's licence "
             "distributed with the data; it may not be redistributed with dpcbench")

#: where each of the paper's sequences (`bench.paper.PAPER_SEQUENCES`, the one list of them and of
#: their row labels) is published and which files to expect: name -> (summary, source, terms,
#: folder, subfolder, pattern, first, count, bit_depth)
_PAPER_FILES: dict[str, tuple] = {
    "longdress": (_8I_SUMMARY, _8I_SOURCE, _8I_TERMS, "longdress", "Ply", "longdress_vox10_{:04d}.ply", 1051, 300, 10),
    "loot": (_8I_SUMMARY, _8I_SOURCE, _8I_TERMS, "loot", "Ply", "loot_vox10_{:04d}.ply", 1000, 300, 10),
    "redandblack": (_8I_SUMMARY, _8I_SOURCE, _8I_TERMS, "redandblack", "Ply", "redandblack_vox10_{:04d}.ply",
                    1450, 300, 10),
    "soldier": (_8I_SUMMARY, _8I_SOURCE, _8I_TERMS, "soldier", "Ply", "soldier_vox10_{:04d}.ply", 536, 300, 10),
    "ulliwegner": (
        "MPEG content repository, 10-bit; MPEG test-material terms",
        "MPEG point cloud test content 'UlliWegner' (a full-body capture; the paper cites MPEG and JPEG Pleno for "
        "its data); distributed to MPEG participants through the MPEG content repository "
        "http://mpegfs.int-evry.fr/ ; outside MPEG ask the content owner named in the repository's readme",
        "MPEG test material: use restricted to research and standardization under the content owner's terms; "
        "it may not be redistributed with dpcbench",
        "ulliwegner", None, None, 0, None, 10),
}
#: the paper's sequences, in the paper's order, titled with its row labels
PAPER: dict[str, PaperDataset] = {name: PaperDataset(name, label, *_PAPER_FILES[name])
                                  for name, label in PAPER_SEQUENCES.items()}

@dataclass(frozen=True)
class MeshDataset:
    """A known mesh sequence read at run time: ``<data dir>/<folder>/<pattern.format(i)>``, i in
    0..count-1. ``params``: its default sampling parameters (`bench.meshseq.load_mesh_sequence`)."""

    name: str
    title: str
    summary: str
    source: str
    terms: str
    folder: str
    pattern: str
    count: int
    params: dict


MESHES: dict[str, MeshDataset] = {
    "samba": MeshDataset(
        "samba", "Samba (MIT)",
        "real captured motion (a dancer in a skirt), 20 OBJ frames of 9,971 vertices / 19,938 faces with shared "
        "connectivity: sampled with exact point correspondence; not one of the paper's sequences",
        "D. Vlasic, I. Baran, W. Matusik, J. Popovic, 'Articulated Mesh Animation from Multi-view Silhouettes', "
        "ACM SIGGRAPH 2008; 'samba' mesh sequence from the authors' page "
        "http://people.csail.mit.edu/drdaniel/mesh_animation/",
        "research data under its owners' terms: read at run time, never redistributed with dpcbench",
        "mit_samba", "samba_{:04d}.obj", 20, {"bit_depth": 10}),
}


def default_data_dirs() -> list[Path]:
    """Where data is looked for when no folder is given: ``../shared/data`` beside the repository."""
    repo = Path(__file__).resolve().parents[1]
    return [repo.parent / "shared" / "data"]


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


def load_mesh_dataset(name: str, frames=None, data_dir=None, *, progress: bool = True, **params) -> Sequence:
    """A registered mesh sequence (``MESHES``), sampled by `bench.meshseq.load_mesh_sequence`."""
    info = MESHES[name]
    folder = find_mesh_folder(info, data_dir)
    if folder is None:
        looked = ", ".join(str(p) for p in ([data_dir_from(data_dir)] if data_dir_from(data_dir) else [])
                           + default_data_dirs())
        raise UserError(f"{info.title}: no {info.folder}/{info.pattern.format(0)} found under {looked}. It is "
                        f"published as: {info.source}. Terms: {info.terms}. Put the frames in <data dir>/{info.folder}/ "
                        f"and pass --data-dir <data dir> (or set {DATA_DIR_ENV}).")
    files = [folder / info.pattern.format(i) for i in range(info.count)]
    missing = [p.name for p in files if not p.is_file()]
    if missing:
        raise UserError(f"{info.title}: {len(missing)} of {info.count} frame files missing from {folder} "
                        f"(first: {missing[0]}); re-copy the sequence")
    indices = _frame_indices(frames, len(files), info.title)
    seq = _mesh_sequence(files, indices, info.name, progress, {**info.params, **params})
    seq.meta.update({"dataset": info.name, "source": info.source, "terms": info.terms, "folder": str(folder)})
    return seq


def _mesh_sequence(files, indices, name, progress, params) -> Sequence:
    import inspect

    from bench.meshseq import load_mesh_sequence

    known = [n for n, p in inspect.signature(load_mesh_sequence).parameters.items()
             if p.kind is inspect.Parameter.KEYWORD_ONLY and n not in ("name", "progress")]
    unknown = sorted(set(params) - set(known))
    if unknown:
        raise UserError(f"{name}: unknown mesh sequence parameter(s) {', '.join(unknown)}; accepted: {', '.join(known)}")
    return load_mesh_sequence(files, indices, name=name, progress=progress, **params)


def _datasets_version() -> str:
    from bench.standins import bunny, human

    return f"human{human.GENERATOR_VERSION}-bunny{bunny.GENERATOR_VERSION}"


#: changes whenever a generator's output changes (run fingerprints use it)
DATASETS_VERSION = _datasets_version()


def parse_frames(text: str | None):
    """CLI frame selection: None, "N" (the first N frames), or a list "0,1,2" / ranges "0-9" -> count or
    list of indices."""
    if text is None or text == "":
        return None
    try:
        if "," not in text and "-" not in text:
            return int(text)
        indices: list[int] = []
        for part in text.split(","):
            part = part.strip()
            if "-" in part:
                a, b = part.split("-", 1)
                indices.extend(range(int(a), int(b) + 1))
            elif part:
                indices.append(int(part))
        return indices
    except ValueError:
        raise UserError(f"--frames {text!r}: give a count (10), a list (0,5,9) or a range (0-9)") from None


def _frame_indices(frames, available: int | None, label: str) -> list[int] | None:
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


def generate_embedded(name: str, frames=None, *, cache: bool = True, progress: bool = True, **params) -> Sequence:
    """Generate (or read from the cache) frames of an embedded sequence."""
    from bench.standins.cache import cache_key, load_cached, store_cached

    info = EMBEDDED[name]
    known = info.parameters()
    unknown = sorted(set(params) - set(known))
    if unknown:
        raise UserError(f"{name}: unknown parameter(s) {', '.join(unknown)}; accepted: "
                        + ", ".join(f"{k} (default {v!r})" for k, v in known.items()))
    from bench.params import check_param_types

    check_param_types(info.generator().generate_frame, params, f"embedded sequence {name}")
    full = {**known, **params}
    indices = _frame_indices(info.default_frames if frames is None else frames, None, name)
    module = info.generator()
    out: list[PointCloud] = []
    iterator: Iterable[int] = indices
    if progress and len(indices) > 1:
        from bench.progress import progress_bar

        iterator = progress_bar(indices, desc=f"generating {name}", unit="frame")
    for index in iterator:
        key = cache_key(name, module.GENERATOR_VERSION, full, index)
        arrays = load_cached(key, name) if cache else None
        if arrays is not None and "normals" not in arrays:  # written by an older dpcbench: regenerate
            arrays = None
        if arrays is None:
            try:
                points, colours, normals = module.generate_frame(index, **full)
            except UserError:
                raise
            except ValueError as err:  # generate_frame's refusal of a parameter value (types checked above)
                raise UserError(f"embedded sequence {name}: {err}") from None
            # voxel indices (<= 16 bits) are stored exactly as uint16; float samples keep float64;
            # normals as float32, the type of the PLY files, so that the frames in memory and the
            # frames written (which pc_error reads) carry the same normals
            arrays = {"points": points if full.get("bit_depth") is None else points.astype(np.uint16),
                      "colors": colours, "normals": normals.astype(np.float32)}
            if cache:
                store_cached(key, name, arrays)
        out.append(PointCloud(arrays["points"].astype(np.float64), arrays["colors"],
                              arrays["normals"].astype(np.float64)))
    bit_depth = full.get("bit_depth")
    meta = {"generator": name, "version": module.GENERATOR_VERSION, "params": full, "frame_indices": indices,
            "description": info.description}
    return Sequence(name, out, None if bit_depth is None else int(bit_depth), [], meta)


def data_dir_from(data_dir: str | os.PathLike | None) -> Path | None:
    """The data folder: the argument, else ``$DPCBENCH_DATA_DIR``, else None."""
    value = data_dir if data_dir not in (None, "") else os.environ.get(DATA_DIR_ENV)
    return Path(value).expanduser() if value else None


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


def load_paper(name: str, frames=None, data_dir=None, progress: bool = True) -> Sequence:
    """Read a paper sequence from the local copy, checking the expected files first."""
    info = PAPER[name]
    root = data_dir_from(data_dir)
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
        indices = _frame_indices(frames, len(files), info.title)
        chosen = [files[i] for i in indices]
    else:
        indices = _frame_indices(frames, len(expected), info.title)
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
    return seq


def load_path(path: str | os.PathLike, frames=None, progress: bool = True) -> Sequence:
    """A user's folder / glob / file of PLY frames."""
    files = list_frame_files(path)
    indices = _frame_indices(frames, len(files), str(path))
    p = Path(str(path))
    label = p.name if p.is_dir() else p.stem
    seq = load_sequence([files[i] for i in indices], name=label, progress=progress)
    seq.meta["source"] = str(path)
    return seq


def load_dataset(name_or_path: str | os.PathLike, frames=None, data_dir=None, *, progress: bool = True,
                 name_only: bool = False, **params) -> Sequence:
    """An embedded sequence, a paper sequence, or a PLY folder/glob/file, as a `Sequence` (see module doc).

    ``params`` go to the embedded generator (e.g. ``size="tiny"``, ``motion="dance"``, ``bit_depth=9``,
    ``seed=1``, ``cache=False``); they are refused for files.
    """
    text = str(name_or_path)
    key = text.lower()
    # a file or folder of a dataset's name in the working directory is what the user has at hand: it
    # is taken, and a note says so (./human is unambiguous); ``name_only`` (configs, whose `name`
    # is always a dataset) never looks on disk
    shadowed = (key in EMBEDDED or key in PAPER) and not name_only and Path(text).exists()
    if shadowed and Path(text).name == text:
        kind = "embedded" if key in EMBEDDED else "paper"
        what = "folder" if Path(text).is_dir() else "file"
        warn(f"{text!r} is both the {kind} sequence {key} and the {what} {Path(text).resolve()}; using the {what} "
             f"(run from another folder for the {kind} sequence, or write ./{text} to silence this note)")
    if key in EMBEDDED and not shadowed:
        cache = params.pop("cache", True)
        return generate_embedded(key, frames, cache=cache, progress=progress, **params)
    if key in MESHES and not Path(text).exists():
        return load_mesh_dataset(key, frames, data_dir, progress=progress, **params)
    from bench.meshseq import list_mesh_files

    mesh_files = list_mesh_files(text)
    if mesh_files is not None:
        p = Path(text)
        indices = _frame_indices(frames, len(mesh_files), text)
        seq = _mesh_sequence(mesh_files, indices, p.name if p.is_dir() else p.stem, progress, params)
        seq.meta["source"] = text
        return seq
    if params:
        raise UserError(f"{text}: parameters ({', '.join(sorted(params))}) apply only to the embedded "
                        f"sequences ({', '.join(EMBEDDED)}) and to mesh sequences ({', '.join(MESHES)}, or a folder "
                        "of OBJ/OFF/PLY meshes)")
    if key in PAPER and not shadowed:
        return load_paper(key, frames, data_dir, progress=progress)
    if not Path(text).exists() and not any(ch in text for ch in "*?["):
        raise UserError(f"{text}: not a dataset name and no such file or folder. Known names: embedded "
                        f"{', '.join(EMBEDDED)}; paper sequences {', '.join(PAPER)} (need --data-dir); mesh "
                        f"sequences {', '.join(MESHES)}; or give a folder of PLY frames or of mesh frames")
    return load_path(text, frames, progress=progress)


def describe_datasets(data_dir=None) -> list[dict]:
    """One row per registered dataset: name, kind, description, available (bool), reason (str)."""
    rows = []
    for info in EMBEDDED.values():
        try:
            params = info.parameters()
            rows.append({"name": info.name, "kind": "embedded", "description": info.description,
                         "available": True, "reason": "", "params": params})
        except ImportError as err:  # a dependency of the generator (e.g. pymeshlab) missing here
            rows.append({"name": info.name, "kind": "embedded", "description": info.description,
                         "available": False, "reason": f"{type(err).__name__}: {err}", "params": {}})
    root = data_dir_from(data_dir)
    for info in PAPER.values():
        reason = ""
        if root is None:
            reason = f"no data folder (--data-dir or {DATA_DIR_ENV})"
        elif not root.is_dir():
            reason = f"data folder {root} does not exist"
        else:
            folder = find_paper_folder(info, root)
            if folder is None:
                reason = f"no {info.folder} PLY frames under {root}"
            else:
                expected = expected_files(info)
                if expected is not None:
                    missing = sum(not (folder / f).is_file() for f in expected)
                    if missing:
                        reason = f"{missing} of {len(expected)} frame files missing in {folder}"
        rows.append({"name": info.name, "kind": "paper", "description": f"{info.title}: {info.summary}",
                     "terms": info.terms, "available": not reason, "reason": reason})
    for info in MESHES.values():
        folder = find_mesh_folder(info, data_dir)
        rows.append({"name": info.name, "kind": "mesh", "description": f"{info.title}: {info.summary}",
                     "terms": info.terms, "available": folder is not None,
                     "reason": "" if folder else f"no {info.folder}/ found (--data-dir, {DATA_DIR_ENV} or ../shared/data)"})
    return rows
