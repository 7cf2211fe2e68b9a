"""The import layers, file by file on the source (AST, so a lazy import inside a function counts too):

1. metrics < holes < methods < bench: a module imports only from its own package or a lower one (the numpy API
   never imports the harness).
2. Inside methods, no method imports another: a method module (one a `methods.registry` entry names, a package's
   submodules included) imports the shared modules (``base``, ``registry``, the ``_``-prefixed helpers) and its
   own package only, and a shared module imports no method module. Shared geometry lives below the methods
   (``methods._geometry``).
3. Inside bench, the sub-packages are layers too (`BENCH_LAYERS`, lowest first): core < data < experiment <
   execution < results < reporting < testing < cli; a module imports only its own sub-package or a lower one.
   ``dpcbench.bench`` itself holds only the version."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
LAYERS = ["metrics", "holes", "methods", "bench"]
PREFIX = "dpcbench."
#: installed names that are not a top-level folder, and the layer of the folder they live in
ALIASES = {"testing": "bench"}  # dpcbench.testing is bench/testing (pyproject's package-dir)

#: bench's sub-packages, lowest first (``testing`` is bench/testing, installed as ``dpcbench.testing``)
BENCH_LAYERS = ["core", "data", "experiment", "execution", "results", "reporting", "testing", "cli"]

#: known imports of a method module from below, each with the reason it is still there
KNOWN_METHOD_IMPORTS = {
    # step 6e's membrane is LozesPDE's graph fill (seed_hole / evolve); moving the graph below the methods is open
    ("methods/_spatial_fill/membrane.py", "dpcbench.methods.lozes_pde"),
}


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, dotted module) of every absolute import in ``path``; ``from a import b`` gives ``a.b`` too (b may
    be a module)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found += [(node.lineno, node.module)] + [(node.lineno, f"{node.module}.{a.name}") for a in node.names]
        elif isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
    return found


def _project_imports(path: Path) -> list[tuple[int, str]]:
    """(line, layer) of every import of one of the project's packages (``dpcbench.<layer>...``, or an
    `ALIASES` name)."""
    found = []
    for line, name in _imports(path):
        top = name.removeprefix(PREFIX).split(".")[0] if name.startswith(PREFIX) else ""
        layer = ALIASES.get(top, top)
        if layer in LAYERS and (line, layer) not in found:
            found.append((line, layer))
    return found


def _method_modules() -> set[str]:
    """The dotted names of the modules the registry's entries live in (``dpcbench.methods.reference``, ...)."""
    from dpcbench.methods.registry import METHODS

    return {METHODS[name].partition(":")[0] for name in METHODS}


def _owner(module: str, method_modules: set[str]) -> str | None:
    """The method module that ``module`` is (or lies inside), or None for a shared module."""
    return next((m for m in method_modules if module == m or module.startswith(m + ".")), None)


def method_import_violations(files: list[Path], root: Path, method_modules: set[str]) -> list[str]:
    """'path:line imports module' for every import of a method module from another method's or a shared module."""
    out = []
    for path in files:
        rel = path.relative_to(root)
        dotted = PREFIX + ".".join(rel.with_suffix("").parts).removesuffix(".__init__")
        own = _owner(dotted, method_modules)
        for line, name in _imports(path):
            target = _owner(name, method_modules)
            if target is not None and target != own and (rel.as_posix(), target) not in KNOWN_METHOD_IMPORTS:
                out.append(f"{rel.as_posix()}:{line} imports {name}")
    return sorted(set(out))


@pytest.mark.parametrize("package", LAYERS)
def test_packages_import_only_their_own_or_a_lower_layer(package):
    rank = LAYERS.index(package)
    files = sorted((REPO / package).rglob("*.py"))
    assert files, f"{package}/ has no Python files"
    back_edges = [f"{path.relative_to(REPO)}:{line} imports {top}"
                  for path in files for line, top in _project_imports(path) if LAYERS.index(top) > rank]
    assert not back_edges, f"{package} may import only {LAYERS[:rank + 1]}:\n" + "\n".join(back_edges)


def test_no_method_imports_another():
    files = sorted((REPO / "methods").rglob("*.py"))
    violations = method_import_violations(files, REPO, _method_modules())
    assert not violations, "a method module imports another method's module:\n" + "\n".join(violations)


def test_the_layer_check_sees_lazy_and_package_imports(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("import numpy\nimport dpcbench.holes.base\n\ndef f():\n"
                      "    from dpcbench.bench.core.errors import UserError\n    from dpcbench import metrics\n"
                      "    from dpcbench.testing import check_method\nimport bench.results.store\n")
    assert _project_imports(module) == [(2, "holes"), (5, "bench"), (6, "metrics"), (7, "bench")]


def test_the_method_check_sees_one_method_importing_another(tmp_path):
    """The checker itself: a lazy import of another method's module, from a method or from a shared helper, is
    reported; a method's own package, the shared modules and the registry's strings are not."""
    methods = tmp_path / "methods"
    (methods / "fusion").mkdir(parents=True)
    (methods / "fusion" / "__init__.py").write_text("from dpcbench.methods.fusion.stage import run\n")
    (methods / "fusion" / "stage.py").write_text("from dpcbench.methods import _geometry\n\ndef run():\n"
                                                 "    from dpcbench.methods.pde import sampling_step\n")
    (methods / "_helper.py").write_text("from dpcbench.methods.pde import LozesPDE\n")
    (methods / "pde.py").write_text("from dpcbench.methods._helper import x\n")
    files = sorted(methods.rglob("*.py"))
    found = method_import_violations(files, tmp_path, {"dpcbench.methods.fusion", "dpcbench.methods.pde"})
    assert found == ["methods/_helper.py:1 imports dpcbench.methods.pde",
                     "methods/_helper.py:1 imports dpcbench.methods.pde.LozesPDE",
                     "methods/fusion/stage.py:4 imports dpcbench.methods.pde",
                     "methods/fusion/stage.py:4 imports dpcbench.methods.pde.sampling_step"]


def _bench_layer_of_import(name: str) -> str | None:
    """The bench sub-package an import names (``dpcbench.bench.results.store`` -> results, ``dpcbench.testing`` ->
    testing), None for any other import and for ``dpcbench.bench`` itself (the version)."""
    if name == "dpcbench.testing" or name.startswith("dpcbench.testing."):
        return "testing"
    parts = name.split(".")
    if parts[:2] == ["dpcbench", "bench"] and len(parts) > 2 and parts[2] in BENCH_LAYERS:
        return parts[2]
    return None


def bench_layer_violations(bench_root: Path) -> list[str]:
    """'path:line (layer) imports module (layer)' for every import of a higher bench sub-package."""
    out = []
    for layer in BENCH_LAYERS:
        rank = BENCH_LAYERS.index(layer)
        for path in sorted((bench_root / layer).rglob("*.py")):
            for line, name in _imports(path):
                target = _bench_layer_of_import(name)
                if target is not None and BENCH_LAYERS.index(target) > rank:
                    out.append(f"{path.relative_to(bench_root.parent).as_posix()}:{line} ({layer}) imports {name} "
                               f"({target})")
    return sorted(set(out))


def test_bench_sub_packages_are_layers():
    present = sorted(p.name for p in (REPO / "bench").iterdir() if p.is_dir() and (p / "__init__.py").is_file())
    assert set(present) - {"presets", "static"} == set(BENCH_LAYERS), (
        "a bench sub-package is not in BENCH_LAYERS (give it a place in the order): " + ", ".join(present))
    loose = sorted(p.name for p in (REPO / "bench").glob("*.py") if p.name != "__init__.py")
    assert not loose, f"modules directly in bench/ belong in a layer sub-package: {loose}"
    violations = bench_layer_violations(REPO / "bench")
    assert not violations, "a bench module imports a higher layer:\n" + "\n".join(violations)


def test_the_bench_layer_check_sees_an_upward_import(tmp_path):
    bench = tmp_path / "bench"
    for layer in BENCH_LAYERS:
        (bench / layer).mkdir(parents=True)
    (bench / "core" / "a.py").write_text("def f():\n    from dpcbench.bench.results.store import ResultsStore\n")
    (bench / "data" / "b.py").write_text("from dpcbench.bench.core import errors\nimport dpcbench.testing\n")
    (bench / "cli" / "c.py").write_text("from dpcbench.bench.reporting import paper\nfrom dpcbench.bench import __version__\n")
    assert bench_layer_violations(bench) == [
        "bench/core/a.py:2 (core) imports dpcbench.bench.results.store (results)",
        "bench/core/a.py:2 (core) imports dpcbench.bench.results.store.ResultsStore (results)",
        "bench/data/b.py:2 (data) imports dpcbench.testing (testing)"]


def command_import_violations(commands: Path) -> list[str]:
    """'file:line imports module' for every import of one command module from another (what they share lives
    in `dpcbench.bench.cli.options`)."""
    out = []
    for path in sorted(commands.glob("*.py")):
        for line, name in _imports(path):
            parts = name.split(".")
            if parts[:4] == ["dpcbench", "bench", "cli", "commands"] and len(parts) > 4 and parts[4] != path.stem:
                out.append(f"{path.name}:{line} imports {name}")
    return sorted(set(out))


def test_no_command_imports_another(tmp_path):
    assert command_import_violations(REPO / "bench" / "cli" / "commands") == []
    (tmp_path / "a.py").write_text("def f():\n    from dpcbench.bench.cli.commands.b import g\n")
    (tmp_path / "b.py").write_text("from dpcbench.bench.cli.options import load_input\n")
    assert command_import_violations(tmp_path) == ["a.py:2 imports dpcbench.bench.cli.commands.b",
                                                   "a.py:2 imports dpcbench.bench.cli.commands.b.g"]
