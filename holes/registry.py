"""Hole generators by name (lazy import strings)."""

from __future__ import annotations

import importlib

# name -> "module:ClassName"; filled in by holes/ modules
GENERATORS: dict[str, str] = {
    "region": "holes.synthetic:RegionHoles",
    "dropout": "holes.synthetic:DropoutHoles",
    "occlusion": "holes.occlusion:OcclusionHoles",
}


def generator_class(name: str):
    if name not in GENERATORS:
        raise KeyError(f"unknown hole generator {name!r}; known generators: {', '.join(sorted(GENERATORS))}")
    module_name, _, attr = GENERATORS[name].partition(":")
    return getattr(importlib.import_module(module_name), attr)


def get_generator(name: str, **params):
    return generator_class(name)(**params)
