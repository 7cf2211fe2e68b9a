"""Hole generators by name (lazy import strings: `holes.lazy.LazyRegistry`)."""

from __future__ import annotations

from dpcbench.holes.lazy import LazyRegistry

#: name -> "module:ClassName"
GENERATORS = LazyRegistry("hole generator", {
    "none": "dpcbench.holes.base:NoHoles",
    "region": "dpcbench.holes.synthetic:RegionHoles",
    "dropout": "dpcbench.holes.synthetic:DropoutHoles",
    "occlusion": "dpcbench.holes.occlusion:OcclusionHoles",
}, plural="generators")


def generator_class(name: str):
    """The class registered as ``name``; KeyError naming the known generators otherwise."""
    return GENERATORS.load(name)


def get_generator(name: str, **params):
    """A configured generator instance: ``get_generator("region", preset="medium")``."""
    return generator_class(name)(**params)
