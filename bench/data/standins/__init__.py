"""Embedded stand-in sequences (the paper's MPEG data are licensed and cannot ship).

- `human`: a procedural human figure in motion, voxelized like 8i data.
- `bunny`: the Stanford bunny scan deformed non-rigidly and moving, resampled per frame.
- `sdf`: signed distance primitives and the narrow-band surface voxelizer used by `human`.
- `cache`: the on-disk frame cache.

Use them through `bench.data.datasets.load_dataset("human", ...)`.
"""
