"""Methods by name. Entries are import strings, so a heavy dependency (pymeshlab, open3d) loads
only when its method is used."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the registry stays import-light: the base class is needed only for the hints
    from methods.base import InpaintingMethod

# name -> "module:ClassName"
METHODS: dict[str, str] = {
    "none": "methods.reference:NoFill",
    "temporal-copy": "methods.reference:TemporalCopy",
    "temporal-graph": "methods.temporal_graph:TemporalGraph",
    "fu-nonlocal": "methods.temporal_graph:FuNonlocal",
    "temporal-fusion": "methods.temporal_fusion:TemporalFusion",
    "lozes-pde": "methods.lozes_pde:LozesPDE",
    "meshlab": "methods.meshlab:MeshlabFill",
}


def method_class(name: str) -> type[InpaintingMethod]:
    if name not in METHODS:
        raise KeyError(f"unknown method {name!r}; known methods: {', '.join(sorted(METHODS))}")
    module_name, _, attr = METHODS[name].partition(":")
    return getattr(importlib.import_module(module_name), attr)


def get_method(name: str, **params: Any) -> InpaintingMethod:
    """A configured method instance: ``get_method("temporal-graph", beta=0.5)``."""
    return method_class(name)(**params)


def available_methods() -> dict[str, str | None]:
    """name -> None when the method imports, else the reason it cannot be used here."""
    status: dict[str, str | None] = {}
    for name in sorted(METHODS):
        try:
            method_class(name)
            status[name] = None
        except ImportError as err:  # an optional dependency missing here: reported, not a crash
            status[name] = f"{type(err).__name__}: {err}"
    return status
