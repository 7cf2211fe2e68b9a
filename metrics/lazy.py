"""Registries by name with lazy imports, shared by methods, hole generators and metrics.

A registry maps a name to an import string ``"package.module:Attr"`` (or, for the built-in metrics,
to the object itself), and resolves three kinds of name:

- a built-in: an entry written in the package (`methods.registry.METHODS`,
  `holes.registry.GENERATORS`, `metrics.registry.METRICS`);
- a plug-in: an entry point of any installed distribution in the registry's group
  (``dpcbench.methods``, ``dpcbench.holes``, ``dpcbench.metrics``), read from the installed
  metadata (`importlib.metadata.entry_points`) the first time a name is looked up or listed; its
  module is imported only when the entry is used;
- an import path ``"package.module:Attr"`` given where a name is expected: resolved against
  ``sys.path``, then the current directory (appended, so it never shadows an installed module), so
  that ``--method mypkg.fills:MyFill`` works on an uninstalled module beside the config.

A plug-in whose name is a built-in's, or a second distribution's entry point of a name already
taken, is refused: not registered, and listed in ``refused`` with the reason (`dpcbench list`
shows it). A plug-in whose module fails to import is reported by `available` with the reason and
raises ImportError only where it is used, so it breaks no other command.

It lives in ``metrics``, the lowest layer (metrics < holes < methods < bench), so that all three
registries share it; `holes.lazy` re-exports it for the harness (`bench.execution.worker` loads run specs'
``entry`` strings with `import_entry`).
"""

from __future__ import annotations

import hashlib
import importlib
import inspect
import os
import re
import sys
from collections.abc import Callable
from typing import Any

#: ``package.module:Attr`` (dotted identifiers on both sides)
_IMPORT_PATH = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*(\.[A-Za-z_]\w*)*$")


class EntryTypeError(ImportError, TypeError):
    """A registry entry that loads but is not what the registry holds (a method entry naming a
    function, say). An ImportError too, so that every caller that reports "cannot be used here" for
    a missing module reports this the same way."""


def is_import_path(name: object) -> bool:
    """True for a string of the form ``"package.module:Attr"``."""
    return isinstance(name, str) and bool(_IMPORT_PATH.match(name))


def import_entry(entry: str):
    """The object named by an import string ``"package.module:Attr"`` (``Attr`` may be dotted).

    Raises ValueError when ``entry`` is not of that form; ImportError / AttributeError (as Python
    raises them) when the module or the attribute does not exist.
    """
    module_name, sep, attr = str(entry).partition(":")
    if not sep or not module_name or not attr:
        raise ValueError(f"import string {entry!r}: expected 'package.module:Attr'")
    obj = importlib.import_module(module_name)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def _import_with_cwd(entry: str):
    """`import_entry`, retried with the current directory at the end of ``sys.path`` when the
    top-level package is not found (an uninstalled plug-in beside the config)."""
    try:
        return import_entry(entry)
    except ModuleNotFoundError as err:
        top = entry.partition(":")[0].split(".")[0]
        cwd = os.getcwd()
        if err.name != top or cwd in sys.path:
            raise
        sys.path.append(cwd)  # kept: a spawned worker inherits sys.path and loads the same entry
        importlib.invalidate_caches()
        return import_entry(entry)


def source_version(obj: Any) -> str:
    """``"sha256:<16 hex>"`` of the source file of the module that defines ``obj`` (line endings
    normalized to ``\\n``): the version of a plug-in that declares none, so that a changed plug-in
    gets new run ids and is rerun (as asv keys benchmarks by their source)."""
    module = sys.modules.get(getattr(obj, "__module__", "") or "")
    path = inspect.getsourcefile(module) if module is not None else None
    if path is None:
        raise ValueError(f"{obj!r}: no source file to hash; declare a `version` on the class")
    with open(path, "rb") as handle:
        data = handle.read().replace(b"\r\n", b"\n")
    return "sha256:" + hashlib.sha256(data).hexdigest()[:16]


def declared_version(obj: Any) -> str | None:
    """The ``version`` a plug-in declares itself: set on its class (or a base class) outside the
    dpcbench package, or on an object (a `Metric`) that has one. None when it only inherits
    dpcbench's default."""
    if getattr(obj, "__module__", "").startswith("dpcbench."):  # a built-in named by import path
        return str(getattr(obj, "version", "1"))
    if isinstance(obj, type):
        for klass in obj.__mro__:
            if "version" in vars(klass) and not klass.__module__.startswith("dpcbench."):
                return str(vars(klass)["version"])
        return None
    version = getattr(obj, "version", None)
    return None if version is None else str(version)


class LazyRegistry(dict):
    """A ``dict`` of name -> ``"module:Attr"`` import strings that loads entries on demand, with the
    plug-ins of entry point ``group`` and import-path names (see the module docstring).

    ``kind`` names what it holds in messages ("method", "hole generator"); ``plural`` the word the
    list of known names uses ("methods", "generators"). ``check(name, obj)`` raises `EntryTypeError` when
    a loaded entry is not what the registry holds (a method class, a `Metric`). Being a dict, it is
    extended (and, in tests, monkeypatched) like one: ``REGISTRY["mine"] = "mypackage.module:MyClass"``;
    such an entry counts as built in (code that registers it is part of the program).
    """

    def __init__(self, kind: str, entries: dict[str, Any], *, plural: str | None = None, group: str | None = None,
                 check: Callable[[str, Any], None] | None = None):
        super().__init__(entries)
        self.kind = kind
        self.plural = plural or f"{kind}s"
        self.group = group
        self.check = check
        #: plug-in name -> the distribution whose entry point registered it
        self.plugins: dict[str, str] = {}
        #: "name (distribution)" -> why that entry point was not registered
        self.refused: dict[str, str] = {}
        self._discovered = group is None

    # -- entry points, read once on first use ------------------------------------------------
    def discover(self, entry_points: Any = None) -> None:
        """Register the entry points of ``group`` (or those given: objects with ``name``, ``value``
        and ``dist``, as `importlib.metadata.entry_points` returns). Nothing is imported."""
        self._discovered = True
        if self.group is None:
            return
        if entry_points is None:
            from importlib.metadata import entry_points as find

            try:
                entry_points = find(group=self.group)
            except Exception as err:  # broken metadata of some distribution: no plug-ins, said in `list`
                self.refused[f"({self.group})"] = f"cannot read the installed entry points: {type(err).__name__}: {err}"
                return
        for ep in entry_points:
            dist = getattr(getattr(ep, "dist", None), "name", None) or "?"
            label = f"{ep.name} ({dist})"
            taken = dict.__contains__(self, ep.name)
            if taken and ep.name not in self.plugins:
                self.refused[label] = (f"refused: {ep.name!r} is a built-in {self.kind}; give the entry point in "
                                       f"group {self.group} of distribution {dist} another name")
            elif taken:
                self.refused[label] = (f"refused: {ep.name!r} is already registered by distribution "
                                       f"{self.plugins[ep.name]}; rename one of the two entry points")
            elif not is_import_path(ep.value):
                self.refused[label] = (f"refused: entry point value {ep.value!r} is not 'package.module:Attr'")
            else:
                dict.__setitem__(self, ep.name, ep.value)
                self.plugins[ep.name] = dist

    def _ensure(self) -> None:
        if not self._discovered:
            self.discover()

    # -- dict access: plug-ins included, import paths resolve to themselves ------------------
    def __contains__(self, name: object) -> bool:
        self._ensure()
        return dict.__contains__(self, name) or is_import_path(name)

    def entry(self, name: str):
        """What ``name`` is registered as (an import string, or a built-in object); an import path is
        its own entry. KeyError for an unknown name."""
        self._ensure()
        if dict.__contains__(self, name):
            return dict.__getitem__(self, name)
        if is_import_path(name):
            return name
        raise KeyError(name)

    def __getitem__(self, name: str):
        return self.entry(name)

    def get(self, name, default=None):
        return self[name] if name in self else default

    def __iter__(self):
        self._ensure()
        return dict.__iter__(self)

    def __len__(self) -> int:
        self._ensure()
        return dict.__len__(self)

    def keys(self):
        self._ensure()
        return dict.keys(self)

    def items(self):
        self._ensure()
        return dict.items(self)

    def values(self):
        self._ensure()
        return dict.values(self)

    # -- loading ------------------------------------------------------------------------------
    def builtin_names(self) -> list[str]:
        """The names registered in code (the package's own and any added like a dict entry), sorted:
        every name but the entry points' plug-ins."""
        return sorted(name for name in self if name not in self.plugins)

    def is_plugin(self, name: str) -> bool:
        """True for an entry point's name or an import path (code this package does not hold)."""
        self._ensure()
        return name in self.plugins or (is_import_path(name) and not dict.__contains__(self, name))

    def load(self, name: str):
        """The class (or object) registered as ``name``.

        KeyError naming the known ones for an unknown name; ImportError when a plug-in's module
        cannot be imported (whatever it raised, named in the message); `EntryTypeError` (an
        ImportError) when the entry is not what this registry holds.
        """
        if name not in self:
            raise KeyError(f"unknown {self.kind} {name!r}; known {self.plural}: {', '.join(sorted(self))} "
                           f"(or an import path 'package.module:Attr')")
        entry = self.entry(name)
        if not isinstance(entry, str):
            return entry
        if not self.is_plugin(name):
            obj = import_entry(entry)
        else:
            where = f"from distribution {self.plugins[name]}" if name in self.plugins else "by import path"
            try:
                obj = _import_with_cwd(entry)
            except ImportError as err:
                raise ImportError(f"{self.kind} {name!r} ({entry}, {where}) cannot be imported: {err}") from err
            except Exception as err:  # a plug-in's module raised on import: its own bug, reported not raised
                raise ImportError(f"{self.kind} {name!r} ({entry}, {where}) failed to import: "
                                  f"{type(err).__name__}: {err}") from err
        if self.check is not None:
            self.check(name, obj)
        return obj

    def version_of(self, name: str, obj: Any = None) -> str:
        """The version stored results are keyed by: a built-in's ``version`` (checked against its source
        by methods/VERSIONS.toml); a plug-in's declared ``version``, else `source_version` of its
        module."""
        obj = self.load(name) if obj is None else obj
        if not self.is_plugin(name):
            return str(getattr(obj, "version", "1"))
        declared = declared_version(obj)
        return declared if declared is not None else source_version(obj)

    def available(self) -> dict[str, str | None]:
        """name -> None when the entry loads here, else why not (an optional dependency missing, a
        plug-in that fails to import or is not what it should be); refused entry points included
        under ``"name (distribution)"``."""
        status: dict[str, str | None] = {}
        for name in sorted(self):
            try:
                self.load(name)
                status[name] = None
            except ImportError as err:  # reported, not a crash (EntryTypeError included)
                status[name] = f"{type(err).__name__}: {err}"
        status.update(self.refused)
        return status


class ObjectRegistry(LazyRegistry):
    """A `LazyRegistry` whose items are the loaded objects (``REGISTRY[name]`` is the object, not its
    import string): for the metrics, whose built-ins are `Metric` objects that callers read facts
    from (``METRICS[name].level``). A plug-in is imported the first time its item is read, once."""

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self._loaded: dict[str, Any] = {}

    def __getitem__(self, name: str):
        if name not in self._loaded:
            try:
                self._loaded[name] = self.load(name)
            except KeyError:
                raise KeyError(name) from None
        return self._loaded[name]

    def items(self):
        return [(name, self[name]) for name in self]

    def values(self):
        return [self[name] for name in self]
