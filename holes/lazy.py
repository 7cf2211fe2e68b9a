"""Registries by name with lazy imports: ``name -> "module:Attr"``, imported only when used.

The one helper behind `holes.registry.GENERATORS`, `methods.registry.METHODS` and the run specs'
``entry`` strings the worker loads (`bench.worker`): a heavy dependency (open3d, pymeshlab) loads only
when the generator or method that needs it is used, and a spec names its class by import string so
that a spawned worker process loads the same class the driver validated.

It lives in `holes`, the lowest layer that uses it (layers: metrics < holes < methods < bench; a
module imports only from its own layer or a lower one): `methods.registry` and `bench` import it from
here; `metrics` has no lazy registry (its entries are plain functions, all in numpy and scipy).
"""

from __future__ import annotations

import importlib


def import_entry(entry: str):
    """The object named by an import string ``"package.module:Attr"``.

    Raises ValueError when ``entry`` is not of that form; ImportError / AttributeError (as Python
    raises them) when the module or the attribute does not exist.
    """
    module_name, sep, attr = str(entry).partition(":")
    if not sep or not module_name or not attr:
        raise ValueError(f"import string {entry!r}: expected 'package.module:Attr'")
    return getattr(importlib.import_module(module_name), attr)


class LazyRegistry(dict):
    """A ``dict`` of name -> ``"module:Attr"`` import strings that loads entries on demand.

    ``kind`` names what it holds in messages ("method", "hole generator"); ``plural`` the word the
    list of known names uses ("methods", "generators"). Being a dict, it is extended (and, in tests,
    monkeypatched) like one: ``REGISTRY["mine"] = "mypackage.module:MyClass"``.
    """

    def __init__(self, kind: str, entries: dict[str, str], *, plural: str | None = None):
        super().__init__(entries)
        self.kind = kind
        self.plural = plural or f"{kind}s"

    def load(self, name: str):
        """The class (or object) registered as ``name``; KeyError naming the known ones otherwise."""
        if name not in self:
            raise KeyError(f"unknown {self.kind} {name!r}; known {self.plural}: {', '.join(sorted(self))}")
        return import_entry(self[name])

    def available(self) -> dict[str, str | None]:
        """name -> None when the entry imports here, else why not (an optional dependency missing)."""
        status: dict[str, str | None] = {}
        for name in sorted(self):
            try:
                self.load(name)
                status[name] = None
            except ImportError as err:  # an optional dependency missing here: reported, not a crash
                status[name] = f"{type(err).__name__}: {err}"
        return status
