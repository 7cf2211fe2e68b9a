"""The package of another git revision, importable by a child process: for experiments that run the same cases with
this tree and with that revision on one machine (`fusion_golden.py --against`, `blas_threads.py --against`)."""

from __future__ import annotations

import os
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: dpcbench's packages and the folders that hold them (pyproject.toml's package-dir)
PACKAGE_DIRS = {"bench": "bench", "methods": "methods", "metrics": "metrics", "holes": "holes",
                "testing": "bench/testing"}


@contextmanager
def package_of(revision: str) -> Iterator[dict[str, str]]:
    """The environment (os.environ with PYTHONPATH extended) in which ``import dpcbench`` imports git
    ``revision``'s package: its tree in a temporary worktree, reached through a ``dpcbench`` folder of links put
    first on the path. The worktree is removed on exit."""
    with tempfile.TemporaryDirectory() as tmp:
        tree, links = Path(tmp) / "tree", Path(tmp) / "path" / "dpcbench"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), revision], check=True,
                       capture_output=True)
        try:
            links.mkdir(parents=True)
            for name, folder in PACKAGE_DIRS.items():
                (links / name).symlink_to(tree / folder, target_is_directory=True)
            yield {**os.environ, "PYTHONPATH": os.pathsep.join([str(links.parent), os.environ.get("PYTHONPATH", "")])}
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], capture_output=True)
