"""`dpcbench generate NAME --frames N --out DIR`: write an embedded sequence (human, bunny, cow) as binary
PLY frames ``<NAME>_0000.ply ...`` (float x y z, uchar red green blue, float nx ny nz: the stand-in's
exact surface normals, which `dpcbench score` and pc_error use for D2), or a mesh sequence (samba, or a
folder of OBJ/OFF/PLY meshes) sampled into point clouds (float x y z, float nx ny nz from the faces), or
PLY frames (a folder, a paper sequence) re-voxelized on a coarser grid (``--param voxel_size=2``: 10-bit frames
written as 9-bit ones; `bench.data.sequences.coarsened`)."""

from __future__ import annotations

from pathlib import Path

from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    parser = subparsers.add_parser("generate", help="write an embedded or mesh sequence as PLY frames",
                                   description=__doc__)
    parser.add_argument("name", help="embedded sequence name, mesh sequence name (see `dpcbench list`), a "
                                     "folder / glob of mesh frames, or of PLY frames with --param voxel_size=K")
    parser.add_argument("--frames", type=int, default=None, help="number of frames (default: the dataset's)")
    parser.add_argument("--out", required=True, help="output folder (created)")
    parser.add_argument("--param", action="append", metavar="K=V", default=[],
                        help="generator parameter, repeatable: size=tiny|small|default, bit_depth=10, "
                             "motion=walk|dance|wave (human), seed=0, ...; meshes: points=800000 or density=..., "
                             "bit_depth=10|none, seed=0, oversampling=8; PLY frames (a folder, a paper sequence): "
                             "voxel_size=K, written re-voxelized on a grid K times coarser")
    parser.add_argument("--data-dir", default=None, help="folder holding mesh sequences such as mit_samba/")
    parser.add_argument("--no-cache", action="store_true", help="regenerate instead of reading the frame cache")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace existing files in the output folder that dpcbench did not write")
    parser.set_defaults(func=run)


def run(args) -> int:
    from dpcbench.bench.core.params import parse_params
    from dpcbench.bench.data.datasets import EMBEDDED, MESHES, PAPER, load_dataset
    from dpcbench.bench.data.meshseq import list_mesh_files
    from dpcbench.bench.data.outputs import Outputs
    from dpcbench.bench.data.sequences import save_sequence, sequence_file_names
    from dpcbench.bench.data.sources import VOXEL_SIZE
    from dpcbench.bench.data.sources.embedded import check_frames_fit

    name = args.name.lower()
    mesh = name in MESHES or (not Path(args.name).is_file() and list_mesh_files(args.name) is not None)
    params = parse_params(args.param)
    # PLY frames (a folder, a paper sequence) are written again only re-voxelized: that is the one thing to make
    frames_on_disk = not mesh and name not in EMBEDDED and VOXEL_SIZE in params
    if name not in EMBEDDED and not mesh and not frames_on_disk:
        hint = " (a paper sequence: it is read from --data-dir, not generated)" if name in PAPER else ""
        raise UserError(f"{args.name!r} is not an embedded sequence{hint} nor a mesh sequence; choose one of "
                        f"{', '.join(EMBEDDED)}, {', '.join(MESHES)}, give a folder of mesh frames, or a folder of "
                        f"PLY frames with --param {VOXEL_SIZE}=K (written re-voxelized K times coarser)")
    if args.frames is not None and args.frames < 1:
        raise UserError(f"--frames must be at least 1, got {args.frames}")
    guard = Outputs(args.overwrite)
    if frames_on_disk:
        guard.folder(args.out, "--out", sequence=True)
        seq = load_dataset(args.name, frames=args.frames, data_dir=args.data_dir, **params)
    elif name in EMBEDDED:
        count = args.frames if args.frames is not None else EMBEDDED[name].default_frames
        if count > 1:  # frame 0 (generated or cached) sizes the memory the whole count needs
            first = load_dataset(name, frames=1, cache=not args.no_cache, name_only=True, progress=False, **params)
            check_frames_fit(name, count, first.frames[0])
        guard.folder(args.out, "--out", sequence_file_names(name, count), sequence=True)
        seq = load_dataset(name, frames=args.frames, cache=not args.no_cache, name_only=True, **params)
    else:
        guard.folder(args.out, "--out", sequence=True)  # file names follow the mesh sequence's name
        seq = load_dataset(args.name if name not in MESHES else name, frames=args.frames, data_dir=args.data_dir,
                           cache=not args.no_cache, **params)
    out = Path(args.out)
    with guard.staged(out) as stage:  # every frame appears at once, or none
        paths = save_sequence(seq, stage, prefix=seq.name)
    counts = [len(f) for f in seq.frames]
    depth = f", {seq.bit_depth}-bit integer coordinates" if seq.bit_depth else ""
    normals = ", with normals" if seq.frames[0].normals is not None else ""
    print(f"wrote {len(paths)} frames to {out} ({min(counts)}..{max(counts)} points per frame{depth}{normals})")
    return 0
