"""Each registered method's ``version`` beside a hash of the source that computes its output.

Stored results are keyed by a method's ``version``: a change that alters the output must bump it,
or stale results are reused (a forgotten bump once broke CI). As asv does for its benchmarks,
``methods/VERSIONS.toml`` records, for every name in `methods.registry.METHODS`, the version and
the sha256 of its source files; ``tests/test_method_versions.py`` recomputes them and fails when a
source changed while the version did not.

The source files of a method: its own module (a package's ``__init__.py``) plus every module of the
``methods`` package it imports, directly or through another (``_cubes``, ``_graph``, ``_registration``, and a public module
such as ``reference`` whose helpers it calls), lazy imports inside functions included. Left out:
``methods/base.py`` and ``methods/registry.py`` (the interface and the names, shared by all) and
modules outside ``methods`` (``holes.geometry.point_spacing``, ``metrics``), which have their own
versions. The hash is SHA-256 over, per file in path order, the path, a NUL, the file's bytes with
line endings normalized to ``\\n``, and a NUL; so a comment or docstring edit counts too.

After changing a method's source::

    python -m dpcbench.methods.versions --check            # what changed (the test says the same)
    # the output changes: bump `version` in the class, then
    python -m dpcbench.methods.versions --update
    # the output does not change (a refactor, comments): record the new hash, version unchanged
    python -m dpcbench.methods.versions --update --same-output
"""

from __future__ import annotations

import argparse
import ast
import hashlib
import sys
from dataclasses import dataclass
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: tomli is a dependency there
    import tomli as tomllib

from dpcbench.methods.registry import METHODS, method_class

PACKAGE_DIR = Path(__file__).resolve().parent
ROOT = PACKAGE_DIR.parent
VERSIONS_FILE = PACKAGE_DIR / "VERSIONS.toml"
#: shared by every method (interface, names): not part of any method's source
PREFIX = "dpcbench.methods."
SHARED_MODULES = frozenset({"dpcbench.methods.base", "dpcbench.methods.registry", "dpcbench.methods.versions",
                            "dpcbench.methods"})
UPDATE_COMMAND = "python -m dpcbench.methods.versions --update"


@dataclass(frozen=True)
class Record:
    """What VERSIONS.toml holds for one method: class entry, version, hash and the files hashed."""

    entry: str
    version: str
    sha256: str
    files: tuple[str, ...]


def _module_path(module: str) -> Path:
    """The source file of a ``dpcbench.methods.*`` module: ``name.py``, or ``name/__init__.py`` for a package."""
    stem = PACKAGE_DIR / module.removeprefix(PREFIX).replace(".", "/")
    package = stem / "__init__.py"
    return package if package.is_file() and not stem.with_suffix(".py").is_file() else stem.with_suffix(".py")


def _imported_methods_modules(module: str) -> set[str]:
    """The ``dpcbench.methods.*`` modules one module imports anywhere in its source (lazy imports included)."""
    tree = ast.parse(_module_path(module).read_text(encoding="utf-8"))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        found.update(n for n in names if n.startswith(PREFIX) and _module_path(n).is_file())
    return found


def source_modules(name: str) -> list[str]:
    """The modules whose source makes method ``name``'s output (see the module docstring), sorted."""
    if name not in METHODS:
        raise KeyError(f"unknown method {name!r}; known methods: {', '.join(sorted(METHODS))}")
    start = METHODS[name].partition(":")[0]
    seen: set[str] = set()
    todo = [start]
    while todo:
        module = todo.pop()
        if module in seen or (module in SHARED_MODULES and module != start):
            continue
        seen.add(module)
        todo.extend(_imported_methods_modules(module) - seen)
    return sorted(seen)


def source_files(name: str) -> list[str]:
    """Paths (relative to the repository root, ``/``-separated) of ``source_modules(name)``."""
    return sorted(_module_path(m).relative_to(ROOT).as_posix() for m in source_modules(name))


def source_hash(files: list[str]) -> str:
    """SHA-256 over the files (path, NUL, content with ``\\n`` line endings, NUL; in path order)."""
    digest = hashlib.sha256()
    for rel in sorted(files):
        digest.update(rel.encode() + b"\0")
        digest.update((ROOT / rel).read_bytes().replace(b"\r\n", b"\n") + b"\0")
    return digest.hexdigest()


def current() -> dict[str, Record]:
    """The record of every registered method as the working tree has it now."""
    records = {}
    for name in METHODS.builtin_names():  # plug-ins are versioned by their own code (metrics.lazy)
        files = source_files(name)
        records[name] = Record(METHODS[name], str(method_class(name).version), source_hash(files), tuple(files))
    return records


def recorded(path: Path = VERSIONS_FILE) -> dict[str, Record]:
    """The records in VERSIONS.toml (empty when the file does not exist)."""
    if not path.is_file():
        return {}
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    return {name: Record(d["class"], str(d["version"]), d["sha256"], tuple(d["files"])) for name, d in data.items()}


def problems(now: dict[str, Record], stored: dict[str, Record]) -> list[str]:
    """One line per method whose record is out of date, saying what to do; empty when all agree."""
    out = []
    for name in sorted(set(now) | set(stored)):
        if name not in stored:
            out.append(f"{name}: not recorded in methods/VERSIONS.toml; record it with `{UPDATE_COMMAND}`")
            continue
        if name not in now:
            out.append(f"{name}: recorded in methods/VERSIONS.toml but no longer registered; "
                       f"drop it with `{UPDATE_COMMAND}`")
            continue
        new, old = now[name], stored[name]
        if new.sha256 == old.sha256 and new.files == old.files:
            if new.version != old.version:
                out.append(f"{name}: version {old.version} -> {new.version} with the same source; "
                           f"record the new version with `{UPDATE_COMMAND}`")
            continue
        if new.version == old.version:
            out.append(f"{name}: the source ({', '.join(new.files)}) changed but version is still {new.version}: "
                       f"bump version and update the hash with `{UPDATE_COMMAND}` (or, when the output is "
                       f"unchanged, `{UPDATE_COMMAND} --same-output`)")
        else:
            out.append(f"{name}: version {old.version} -> {new.version} and a new source; "
                       f"update the hash with `{UPDATE_COMMAND}`")
    return out


def render(records: dict[str, Record]) -> str:
    """VERSIONS.toml's text (one table per method, names sorted)."""
    lines = ["# Generated by `python -m dpcbench.methods.versions --update`; do not edit by hand.",
             "# For each registered method: its class, `version`, and the sha256 of the source files",
             "# that compute its output (see methods/versions.py). tests/test_method_versions.py checks it.", ""]
    for name in sorted(records):
        rec = records[name]
        files = ", ".join(f'"{f}"' for f in rec.files)
        lines += [f'["{name}"]', f'class = "{rec.entry}"', f'version = "{rec.version}"',
                  f'sha256 = "{rec.sha256}"', f"files = [{files}]", ""]
    return "\n".join(lines)


def update(same_output: bool = False, path: Path = VERSIONS_FILE) -> list[str]:
    """Rewrite VERSIONS.toml from the working tree; return the lines of what changed.

    Refuses (ValueError, nothing written) when a method's source changed but its version did not,
    unless ``same_output`` says the change leaves every output as it was.
    """
    now, stored = current(), recorded(path)
    unbumped = [name for name in now if name in stored and now[name].version == stored[name].version
                and (now[name].sha256, now[name].files) != (stored[name].sha256, stored[name].files)]
    if unbumped and not same_output:
        raise ValueError(f"the source of {', '.join(unbumped)} changed but the version did not: bump `version` "
                         f"in the class when the output changes, or pass --same-output when it does not")
    changes = []
    for name in sorted(set(now) | set(stored)):
        rec = now.get(name)
        if rec != stored.get(name):
            changes.append(f"{name}: removed" if rec is None else
                           f"{name}: version {rec.version}, sha256 {rec.sha256[:12]}, {len(rec.files)} file(s)")
    path.write_text(render(now), encoding="utf-8")
    return changes


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dpcbench.methods.versions", description=__doc__.split("\n\n")[0])
    action = parser.add_mutually_exclusive_group()
    action.add_argument("--check", action="store_true", help="list the out-of-date records (the default)")
    action.add_argument("--update", action="store_true", help="rewrite methods/VERSIONS.toml from the sources")
    parser.add_argument("--same-output", action="store_true",
                        help="with --update: record new hashes of changed sources whose version was not bumped "
                             "(a refactor that leaves every output unchanged)")
    args = parser.parse_args(argv)
    if args.same_output and not args.update:
        parser.error("--same-output goes with --update")
    if args.update:
        try:
            changes = update(same_output=args.same_output)
        except ValueError as err:
            print(f"dpcbench.methods.versions: error: {err}", file=sys.stderr)
            return 2
        print("\n".join(f"updated: {line}" for line in changes) or "methods/VERSIONS.toml was up to date")
        return 0
    found = problems(current(), recorded())
    print("\n".join(found) or "methods/VERSIONS.toml is up to date")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
