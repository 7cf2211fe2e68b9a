"""The import layers: metrics < holes < methods < bench. A module may import only from its
own package or a lower one, at module level or inside a function; the numpy API never imports the
harness. Checked on the source (AST), so a lazy import inside a function counts too."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
LAYERS = ["metrics", "holes", "methods", "bench"]


def _project_imports(path: Path) -> list[tuple[int, str]]:
    """(line, top-level package) of every absolute import of one of the project's packages."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            continue
        found += [(node.lineno, n.split(".")[0]) for n in names if n.split(".")[0] in LAYERS]
    return found


@pytest.mark.parametrize("package", LAYERS)
def test_packages_import_only_their_own_or_a_lower_layer(package):
    rank = LAYERS.index(package)
    files = sorted((REPO / package).rglob("*.py"))
    assert files, f"{package}/ has no Python files"
    back_edges = [f"{path.relative_to(REPO)}:{line} imports {top}"
                  for path in files for line, top in _project_imports(path) if LAYERS.index(top) > rank]
    assert not back_edges, f"{package} may import only {LAYERS[:rank + 1]}:\n" + "\n".join(back_edges)


def test_the_layer_check_sees_lazy_imports(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("import numpy\n\ndef f():\n    from bench.errors import UserError\n    import holes.base\n")
    assert _project_imports(module) == [(4, "bench"), (5, "holes")]
