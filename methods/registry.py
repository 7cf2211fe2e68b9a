"""Methods by name. Entries are import strings (`holes.lazy.LazyRegistry`), so a heavy dependency
(pymeshlab, open3d) loads only when its method is used."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from dpcbench.holes.lazy import LazyRegistry

if TYPE_CHECKING:  # the registry stays import-light: the base class is needed only for the hints
    from dpcbench.methods.base import InpaintingMethod

#: name -> "module:ClassName"
METHODS = LazyRegistry("method", {
    "none": "dpcbench.methods.reference:NoFill",
    "temporal-copy": "dpcbench.methods.reference:TemporalCopy",
    "temporal-graph": "dpcbench.methods.temporal_graph:TemporalGraph",
    "fu-nonlocal": "dpcbench.methods.temporal_graph:FuNonlocal",
    "temporal-fusion": "dpcbench.methods.temporal_fusion:TemporalFusion",
    "lozes-pde": "dpcbench.methods.lozes_pde:LozesPDE",
    "meshlab": "dpcbench.methods.meshlab:MeshlabFill",
})


def method_class(name: str) -> type[InpaintingMethod]:
    """The class registered as ``name``; KeyError naming the known methods otherwise."""
    return METHODS.load(name)


def get_method(name: str, **params: Any) -> InpaintingMethod:
    """A configured method instance: ``get_method("temporal-graph", beta=0.5)``."""
    return method_class(name)(**params)


def available_methods() -> dict[str, str | None]:
    """name -> None when the method imports, else the reason it cannot be used here."""
    return METHODS.available()
