"""Methods by name: the built-ins below, the entry points of group ``dpcbench.methods`` of any
installed distribution, and import paths ``"package.module:Class"`` given as a name (see
`metrics.lazy.LazyRegistry`). Entries are import strings, so a heavy dependency (pymeshlab, open3d)
or a plug-in's module loads only when its method is used."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from dpcbench.holes.lazy import EntryTypeError, LazyRegistry

if TYPE_CHECKING:  # the registry stays import-light: the base class is needed only for the hints
    from dpcbench.methods.base import InpaintingMethod


def _check_method(name: str, obj: Any) -> None:
    from dpcbench.methods.base import InpaintingMethod

    if not (isinstance(obj, type) and issubclass(obj, InpaintingMethod)):
        raise EntryTypeError(f"method {name!r} is {obj!r}, not a subclass of dpcbench.methods.base.InpaintingMethod")


#: name -> "module:ClassName"
METHODS = LazyRegistry("method", {
    "none": "dpcbench.methods.reference:NoFill",
    "temporal-copy": "dpcbench.methods.reference:TemporalCopy",
    "temporal-graph": "dpcbench.methods.temporal_graph:TemporalGraph",
    "fu-nonlocal": "dpcbench.methods.temporal_graph:FuNonlocal",
    "temporal-fusion": "dpcbench.methods.temporal_fusion:TemporalFusion",
    "lozes-pde": "dpcbench.methods.lozes_pde:LozesPDE",
    "meshlab": "dpcbench.methods.meshlab:MeshlabFill",
}, group="dpcbench.methods", check=_check_method)


def method_class(name: str) -> type[InpaintingMethod]:
    """The class registered as ``name`` (or named by an import path); KeyError naming the known
    methods otherwise, ImportError when its module cannot be imported here."""
    return METHODS.load(name)


def get_method(name: str, **params: Any) -> InpaintingMethod:
    """A configured method instance: ``get_method("temporal-graph", beta=0.5)``."""
    return method_class(name)(**params)


def available_methods() -> dict[str, str | None]:
    """name -> None when the method imports, else the reason it cannot be used here (refused
    plug-in entry points included, as ``"name (distribution)"``)."""
    return METHODS.available()


def method_version(name: str, cls: type[InpaintingMethod] | None = None) -> str:
    """The version stored results of ``name`` are keyed by (`LazyRegistry.version_of`): a built-in's
    ``version``; a plug-in's declared ``version``, else the sha256 of its module's source."""
    return METHODS.version_of(name, cls)
