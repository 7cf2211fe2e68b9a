"""The import graph of the project's modules, read from the source with `ast` (nothing is imported).

    python -m tests.import_graph            # for each bench module, the bench modules it imports
    python -m tests.import_graph --all      # every project module (bench, holes, methods, metrics)

Every import counts, top-level and inside functions alike: a lazy import inside a function is still
a dependency (and a cycle through it is still a cycle a reader has to untangle). Imports under
``if TYPE_CHECKING:`` do not: they name a type for the checker and never run. ``dpcbench.`` in
front of a name is dropped, so the graph reads the same whether the packages are imported by their
folder names or under the ``dpcbench`` namespace.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("metrics", "holes", "methods", "bench")  # layer order: each may import only its own or lower ones


def module_files(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file of the project's packages."""
    files = {}
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            files[".".join(parts)] = path
    return files


def _strip(name: str) -> str:
    return name.removeprefix("dpcbench.")


def _is_type_checking_block(node: ast.AST) -> bool:
    """``if TYPE_CHECKING:`` (or ``typing.TYPE_CHECKING``) with no ``else``."""
    if not isinstance(node, ast.If) or node.orelse:
        return False
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def imports_of(module: str, path: Path, known: set[str]) -> set[str]:
    """The project modules ``module`` imports (``from pkg import mod`` counts as ``pkg.mod`` when that
    is a module, else as ``pkg``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    type_only = {id(n) for block in ast.walk(tree) if _is_type_checking_block(block) for n in ast.walk(block)}
    for node in ast.walk(tree):
        if id(node) in type_only:
            continue  # under `if TYPE_CHECKING:`: read by the type checker only, never run
        if isinstance(node, ast.Import):
            names = [_strip(alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative import: resolve against this module's package
                base = module.split(".") if is_package else module.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = _strip(node.module or "")
            names = [f"{prefix}.{alias.name}" if f"{prefix}.{alias.name}" in known else prefix
                     for alias in node.names]
        else:
            continue
        for name in names:
            # the longest known module that the name starts with (bench.data.plyio.PointCloud -> bench.data.plyio)
            parts = name.split(".")
            while parts and ".".join(parts) not in known:
                parts.pop()
            if parts and ".".join(parts) != module:
                found.add(".".join(parts))
    return found


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """module -> the project modules it imports."""
    files = module_files(root)
    known = set(files)
    return {name: imports_of(name, path, known) for name, path in files.items()}


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted; [] when acyclic."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(components)


def layer_violations(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """(importer, imported) pairs where a module imports a higher layer (metrics < holes < methods < bench)."""
    rank = {p: i for i, p in enumerate(PACKAGES)}
    return sorted((a, b) for a, deps in graph.items() for b in deps
                  if rank[b.split(".")[0]] > rank[a.split(".")[0]])


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    graph = import_graph()
    shown = PACKAGES if "--all" in argv else ("bench",)
    for name in sorted(graph):
        if name.split(".")[0] in shown:
            deps = sorted(d for d in graph[name] if d.split(".")[0] in shown)
            print(f"{name}: {', '.join(deps) if deps else '-'}")
    cycles = find_cycles(graph)
    print("cycles: " + ("; ".join(" <-> ".join(c) for c in cycles) if cycles else "none"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
