"""Hole generators by name: the built-ins below, the entry points of group ``dpcbench.holes`` of any
installed distribution, and import paths ``"package.module:Class"`` (see `metrics.lazy`)."""

from __future__ import annotations

from typing import Any

from dpcbench.holes.lazy import EntryTypeError, LazyRegistry


def _check_generator(name: str, obj: Any) -> None:
    from dpcbench.holes.base import HoleGenerator

    if not (isinstance(obj, type) and issubclass(obj, HoleGenerator)):
        raise EntryTypeError(f"hole generator {name!r} is {obj!r}, not a subclass of dpcbench.holes.base.HoleGenerator")


#: name -> "module:ClassName"
GENERATORS = LazyRegistry("hole generator", {
    "none": "dpcbench.holes.base:NoHoles",
    "region": "dpcbench.holes.synthetic:RegionHoles",
    "dropout": "dpcbench.holes.synthetic:DropoutHoles",
    "occlusion": "dpcbench.holes.occlusion:OcclusionHoles",
}, plural="generators", group="dpcbench.holes", check=_check_generator)


def generator_class(name: str):
    """The class registered as ``name``; KeyError naming the known generators otherwise."""
    return GENERATORS.load(name)


def get_generator(name: str, **params):
    """A configured generator instance: ``get_generator("region", preset="medium")``."""
    return generator_class(name)(**params)
