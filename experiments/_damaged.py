"""Read a `dpcbench damage` output folder for the experiment scripts beside this file."""

from pathlib import Path

import numpy as np

from dpcbench.bench.data.plyio import read_ply
from dpcbench.holes.regions import regions_from_json


def read_damage_output(folder: Path):
    """(frame files, frames, regions) of a damage output folder, or None when it holds no PLY frames and holes.json."""
    files = sorted(folder.glob("*.ply"))
    if not files or not (folder / "holes.json").is_file():
        return None
    frames = [np.asarray(read_ply(p).points, dtype=np.float64) for p in files]
    return files, frames, regions_from_json(folder / "holes.json", len(frames))


def load_damage_or_exit(folder: Path):
    """`read_damage_output` of ``folder``, or a one-line error and exit status 2 when it holds no damage output."""
    import sys

    loaded = read_damage_output(folder)
    if loaded is None:
        print(f"error: {folder} holds no PLY frames and holes.json; run `dpcbench damage` first", file=sys.stderr)
        raise SystemExit(2)
    return loaded
