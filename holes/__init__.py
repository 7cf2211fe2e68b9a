"""Hole generators (damage with ground truth) and hole detection, on plain numpy arrays.

A frame is an (N, 3) float array; a sequence is a list of them. Nothing here depends on `bench`.
"""

from holes.regions import HoleRegion, regions_from_json, regions_to_json

__all__ = ["HoleRegion", "regions_from_json", "regions_to_json"]
