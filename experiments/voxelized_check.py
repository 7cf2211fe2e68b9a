"""Which sequences of the presets the methods treat as voxelized: integer coordinates at a point spacing of at
most `VOXELIZED_SPACING_MAX` voxels (`metrics.neighbours.is_voxelization`, used by temporal-fusion, fu-nonlocal and
temporal-graph). temporal-fusion 52, fu-nonlocal 8 and temporal-graph 10 changed only what happens to integer data
sparser than that, so where every integer sequence prints a spacing of at most 1.5, they give those presets' runs
the output of the versions before.

    .venv/bin/python experiments/voxelized_check.py [PRESET_OR_TOML ...]   # default: every preset in bench/presets

One line per distinct sequence: the preset that lists it first, its name, integer or float, the point spacing of
its largest frame (`metrics.neighbours.point_spacing`), that frame's points, and whether it counts as voxelized.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dpcbench.bench.data.datasets import load_run_sequence
from dpcbench.bench.experiment.config import load_config
from dpcbench.metrics.neighbours import is_voxelization, point_spacing

PRESETS = Path(__file__).resolve().parent.parent / "bench" / "presets"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("configs", nargs="*", help="preset names or TOML files (default: every preset)")
    args = parser.parse_args(argv)
    paths = [PRESETS / f"{c}.toml" if not c.endswith(".toml") else Path(c) for c in args.configs] or \
        sorted(PRESETS.glob("*.toml"))
    seen = set()
    for path in paths:
        for sequence in load_config(path).sequences:
            key = repr(sequence)
            if key in seen:
                continue
            seen.add(key)
            try:
                frames = load_run_sequence(sequence).points
            except Exception as error:  # noqa: BLE001  (data not on this machine: said, not fatal)
                print(f"{path.stem}: {key[:70]}: not loaded ({str(error).splitlines()[0][:100]})")
                continue
            largest = max(frames, key=len)
            integer = all(np.array_equal(f, np.round(f)) for f in frames)
            spacing = point_spacing(largest)
            voxelized = is_voxelization(frames)
            print(f"{path.stem}: {getattr(sequence, 'label', None) or getattr(sequence, 'name', key[:60])}: "
                  f"{'integer' if integer else 'float'}, spacing {spacing:.3f}, {len(largest)} points, "
                  f"{'voxelized' if voxelized else 'not voxelized'}")


if __name__ == "__main__":
    main()
