"""The dataset registry: embedded stand-in sequences, the paper's sequences, mesh sequences, and the
one resolver from a name or path to a sequence source (`bench.data.sources`).

``resolve_source(name_or_path, data_dir=None)`` -> a `bench.data.sources.SequenceSource`;
``load_dataset(name_or_path, frames=None, data_dir=None, **params) -> Sequence`` resolves and loads:

- an embedded name (``EMBEDDED``: "human", "bunny", "cow") generates the frames (deterministic for the
  same parameters; cached on disk, see `bench.data.standins.cache`);
- a paper sequence name (``PAPER``: longdress, loot, redandblack, soldier, ulliwegner) reads the
  user's local copy from ``data_dir`` or ``$DPCBENCH_DATA_DIR``, after checking that the expected
  files are there; these data are licensed and cannot ship with dpcbench;
- a mesh sequence name (``MESHES``: "samba") samples the mesh frames found under ``data_dir``,
  ``$DPCBENCH_DATA_DIR`` or the repository's ``../shared/data`` (see `bench.data.meshseq`);
- anything else is a path: a folder of PLY frames, a glob, or one PLY file; a folder (or glob) of mesh
  frames (OBJ, OFF, PLY with faces) is sampled into point clouds by `bench.data.meshseq` and takes its
  parameters (points, density, bit_depth, seed, oversampling, drop_degenerate, cache).

``frames``: None (embedded: ``default_frames``; files: all), a count N (the first N), or an iterable
of frame indices (0 = the first frame of the sequence).

Every user mistake (unknown name, missing data, bad parameter) raises `bench.core.errors.UserError` with
a message that says what to do.
"""

from __future__ import annotations

import os
from pathlib import Path

from dpcbench.bench.core.errors import UserError, warn
from dpcbench.bench.core.paper_facts import PAPER_SEQUENCES
from dpcbench.bench.core.params import parse_param_value, parse_params  # noqa: F401  (the one --param parser)
from dpcbench.bench.data.sequences import Sequence
from dpcbench.bench.data.sources import DATA_DIR_ENV, SequenceSource, data_dir_from
from dpcbench.bench.data.sources.embedded import EmbeddedDataset, EmbeddedSource
from dpcbench.bench.data.sources.meshes import (
    MeshDataset,
    MeshDatasetSource,
    MeshFolderSource,
    find_mesh_folder,
)
from dpcbench.bench.data.sources.paper import (
    PaperDataset,
    PaperSource,
    expected_files,
    find_paper_folder,
)
from dpcbench.bench.data.sources.points import PointCloudSource

EMBEDDED: dict[str, EmbeddedDataset] = {
    "human": EmbeddedDataset(
        "human",
        "procedural human figure in motion (walk/dance/wave), smooth-blended body parts, surface voxelized "
        "like 8i data (integer coordinates at bit_depth, one point per surface voxel), with colours; "
        "size=tiny ~24k, small ~96k, default ~575k points per frame",
        "dpcbench.bench.data.standins.human",
    ),
    "bunny": EmbeddedDataset(
        "bunny",
        "the Stanford bunny scan (pymeshlab sample mesh) bent, twisted and bumped non-rigidly while turning, "
        "resampled every frame and voxelized at bit_depth (or float samples with bit_depth=None); "
        "size=tiny ~19k, small ~97k, default ~630k points per frame",
        "dpcbench.bench.data.standins.bunny",
    ),
    "cow": EmbeddedDataset(
        "cow",
        "a walking cow (pymeshlab sample mesh): legs swinging in a trot, head nodding, tail swishing while it "
        "turns; resampled every frame and voxelized at bit_depth (or float samples with bit_depth=None); held-out "
        "data (no default was judged on it); size=tiny ~24k, small ~100k, default ~600k points per frame",
        "dpcbench.bench.data.standins.cow",
    ),
}

_8I_SUMMARY = "8i Voxelized Full Bodies (JPEG Pleno / MPEG), 10-bit, 300 frames; non-commercial research use"
_8I_SOURCE = ("8i Voxelized Full Bodies (8iVFB v2), E. d'Eon, B. Harrison, T. Myers, P. A. Chou, ISO/IEC JTC1/SC29 "
              "WG1 m74006 / WG11 m40059, 2017; download from the JPEG Pleno database "
              "http://plenodb.jpeg.org/pc/8ilabs (also in the MPEG content repository)")
_8I_TERMS = ("free of charge for non-commercial research and standardization use under 8i's licence "
             "distributed with the data; it may not be redistributed with dpcbench")

#: where each of the paper's sequences (`bench.reporting.paper.PAPER_SEQUENCES`, the one list of them and of
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


def _datasets_version() -> str:
    from dpcbench.bench.data.standins import bunny, human

    return f"human{human.GENERATOR_VERSION}-bunny{bunny.GENERATOR_VERSION}"


#: changes whenever the human's or the bunny's output changes (their runs' fingerprints use it)
DATASETS_VERSION = _datasets_version()


def embedded_version(name: str) -> str:
    """The data version in the fingerprint of a run on embedded sequence ``name``: `DATASETS_VERSION` for the human
    and the bunny (one string for both, as their stored runs' ids have it), ``<name><GENERATOR_VERSION>`` for a
    stand-in added after them, so that a change to its generator re-runs only its own runs."""
    if name in ("human", "bunny") or name not in EMBEDDED:
        return DATASETS_VERSION
    return f"{name}{EMBEDDED[name].generator().GENERATOR_VERSION}"


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
                if int(b) - int(a) > MAX_FRAMES:
                    raise UserError(f"--frames {text!r}: more than {MAX_FRAMES} frames; ask for fewer")
                indices.extend(range(int(a), int(b) + 1))
            elif part:
                indices.append(int(part))
    except UserError:
        raise
    except ValueError:
        raise UserError(f"--frames {text!r}: give a count (10), a list (0,5,9) or a range (0-9)") from None
    if any(b <= a for a, b in zip(indices, indices[1:])):
        # a sequence is in time order: a reordered or repeated frame would pair regions, masks and
        # temporal neighbours with the wrong frames
        raise UserError(f"--frames {text!r}: give the frames in increasing order, each once (e.g. 0,5,9)")
    return indices


#: the most frames one sequence selection may name (an embedded stand-in generates every one)
MAX_FRAMES = 10_000
#: the most frames of an embedded stand-in one command generates (each takes seconds to minutes)
MAX_STANDIN_FRAMES = 1_000


def resolve_source(name_or_path: str | os.PathLike, data_dir=None, *, name_only: bool = False,
                   label: str | None = None) -> SequenceSource:
    """The one resolver from a name or path to its `bench.data.sources.SequenceSource`, in this order:

    1. an embedded name (``EMBEDDED``), unless a file or folder of that name is in the working
       directory (it is what the user has at hand: taken, with a note; ``name_only`` never looks on disk);
    2. a registered mesh sequence name (``MESHES``) that is not a path here;
    3. a folder or glob of mesh frames (OBJ, OFF, PLY with faces);
    4. a paper sequence name (``PAPER``), unless shadowed as in 1;
    5. a folder, glob or file of PLY point cloud frames.

    ``data_dir``: where paper and mesh sequences are looked for (default ``$DPCBENCH_DATA_DIR``);
    ``label``: the name of a path source (default: the folder's name). Unknown names that are no path
    raise `UserError` listing the known ones.
    """
    from dpcbench.bench.data.meshseq import list_mesh_files

    text = str(name_or_path)
    key = text.lower()
    shadowed = (key in EMBEDDED or key in PAPER) and not name_only and Path(text).exists()
    if shadowed and Path(text).name == text:
        kind = "embedded" if key in EMBEDDED else "paper"
        what = "folder" if Path(text).is_dir() else "file"
        warn(f"{text!r} is both the {kind} sequence {key} and the {what} {Path(text).resolve()}; using the {what} "
             f"(run from another folder for the {kind} sequence, or write ./{text} to silence this note)")
    if key in EMBEDDED and not shadowed:
        return EmbeddedSource(EMBEDDED[key])
    if key in MESHES and not Path(text).exists():
        return MeshDatasetSource(MESHES[key], data_dir)
    mesh_files = list_mesh_files(text)
    if mesh_files is not None:
        return MeshFolderSource(text, mesh_files, label)
    if key in PAPER and not shadowed:
        return PaperSource(PAPER[key], data_dir)
    if not Path(text).exists() and not any(ch in text for ch in "*?["):
        raise UserError(f"{text}: not a dataset name and no such file or folder. Known names: embedded "
                        f"{', '.join(EMBEDDED)}; paper sequences {', '.join(PAPER)} (need --data-dir); mesh "
                        f"sequences {', '.join(MESHES)}; or give a folder of PLY frames or of mesh frames")
    return PointCloudSource(text, label)


def load_dataset(name_or_path: str | os.PathLike, frames=None, data_dir=None, *, progress: bool = True,
                 name_only: bool = False, **params) -> Sequence:
    """An embedded sequence, a paper sequence, a mesh sequence or a PLY folder/glob/file, as a `Sequence`:
    `resolve_source` then its ``load`` (see the module doc).

    ``params`` go to the embedded generator (e.g. ``size="tiny"``, ``motion="dance"``, ``bit_depth=9``,
    ``seed=1``, ``cache=False``) or to the mesh sampling; PLY frames (a folder, the paper's sequences) take
    only ``voxel_size`` (`bench.data.sequences.coarsened`).
    """
    source = resolve_source(name_or_path, data_dir, name_only=name_only)
    if source.kind == "embedded" and frames is not None:
        top = int(frames) if isinstance(frames, int) else max([int(i) + 1 for i in frames], default=0)
        if top > MAX_STANDIN_FRAMES:
            raise UserError(f"{name_or_path}: {top} frames asked of an embedded stand-in; it generates at most "
                            f"{MAX_STANDIN_FRAMES} (each frame is computed): ask for fewer frames")
    return source.load(frames, progress=progress, **params)


def run_sequence_source(sequence: dict):
    """The source (`bench.data.sources`) of a run spec's ``sequence`` entry: ``name`` (a dataset name, never
    looked up on disk) or ``path`` (named by ``label``), with ``data_dir``."""
    if sequence.get("path"):
        return resolve_source(sequence["path"], label=sequence.get("label") or sequence["name"])
    return resolve_source(sequence["name"], sequence.get("data_dir"), name_only=True)


def load_run_sequence(sequence: dict) -> Sequence:
    """The intact sequence of a run spec's ``sequence`` entry (`bench.experiment.config.RunSpec`; `run_sequence_source`),
    ``frames`` (count, [start, stop) or [start, stop, step]) of it, loaded with its ``params``."""
    frames = sequence.get("frames")
    wanted = None if frames is None else list(range(frames) if isinstance(frames, int) else range(*frames))
    return run_sequence_source(sequence).load(wanted, progress=False, **sequence.get("params", {}))


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
    for paper in PAPER.values():
        reason = ""
        if root is None:
            reason = f"no data folder (--data-dir or {DATA_DIR_ENV})"
        elif not root.is_dir():
            reason = f"data folder {root} does not exist"
        else:
            folder = find_paper_folder(paper, root)
            if folder is None:
                reason = f"no {paper.folder} PLY frames under {root}"
            else:
                expected = expected_files(paper)
                if expected is not None:
                    missing = sum(not (folder / f).is_file() for f in expected)
                    if missing:
                        reason = f"{missing} of {len(expected)} frame files missing in {folder}"
        rows.append({"name": paper.name, "kind": "paper", "description": f"{paper.title}: {paper.summary}",
                     "terms": paper.terms, "available": not reason, "reason": reason})
    for mesh in MESHES.values():
        folder = find_mesh_folder(mesh, data_dir)
        rows.append({"name": mesh.name, "kind": "mesh", "description": f"{mesh.title}: {mesh.summary}",
                     "terms": mesh.terms, "available": folder is not None,
                     "reason": "" if folder else f"no {mesh.folder}/ found (--data-dir, {DATA_DIR_ENV} or ../shared/data)"})
    return rows
