"""Atomic writes: a file (or a folder) appears whole under its final name or not at all.

Everything dpcbench writes for others to read (PLY frames, summaries, figures, pages, cache entries,
run folders, worker outcomes) goes through here: the content is written to a temporary sibling in
the same folder (so the final rename never crosses a filesystem) and renamed over the target with
`os.replace`, which POSIX and Windows make atomic for a single name. A writer killed half-way
leaves only a hidden temporary file; a reader never sees half a file.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str | None = None) -> Iterator[Path]:
    """``with atomic_path(out) as tmp: write(tmp)``: on leaving the block ``tmp`` is renamed to ``out``.

    ``tmp`` is a fresh, unique name beside ``out`` (``.<name>.<random>.tmp<suffix>``); ``suffix``
    defaults to ``out``'s own suffix, so writers that choose the format by extension (matplotlib's
    savefig, numpy's savez) see the right one. The parent folder is created. On an exception inside
    the block the temporary file is removed and ``out`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix if suffix is None else suffix}",
                                dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; returns ``Path(path)``."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)
    return path


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns ``Path(path)``."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return path


#: prefix of the temporary folders `atomic_folder` writes (a reader skips them; see `stale_folders`)
TEMP_FOLDER_PREFIX = ".tmp-"


@contextmanager
def atomic_folder(path: str | os.PathLike) -> Iterator[Path]:
    """``with atomic_folder(run_dir) as tmp: fill(tmp)``: on leaving the block the folder ``tmp``
    takes the name ``path``, replacing a folder of that name if there is one.

    ``tmp`` is ``<parent>/.tmp-<name>-<pid>-<random>``: the writer's process id in the name lets
    `stale_folders` tell a folder still being written from one left by a killed writer. Replacing
    an existing folder is two renames (old -> ``.tmp-old-...``, new -> ``path``) because a rename
    cannot replace a non-empty folder; a reader in between sees no folder, never a half-written one.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / f"{TEMP_FOLDER_PREFIX}{path.name}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    tmp.mkdir()
    try:
        yield tmp
        if path.exists():
            trash = path.parent / f"{TEMP_FOLDER_PREFIX}old-{path.name}-{uuid.uuid4().hex[:8]}"
            os.replace(path, trash)
            os.replace(tmp, path)
            shutil.rmtree(trash, ignore_errors=True)
        else:
            os.replace(tmp, path)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _writer_alive(folder: Path) -> bool:
    """True while the process named in an `atomic_folder` temporary folder's name still runs."""
    parts = folder.name.split("-")
    if len(parts) < 4 or parts[1] == "old" or not parts[-2].isdigit():
        return False
    try:
        os.kill(int(parts[-2]), 0)
    except (ProcessLookupError, PermissionError):
        return False
    return True


def remove_stale_folders(parent: str | os.PathLike) -> int:
    """Remove the `atomic_folder` temporary folders in ``parent`` whose writer process is gone (left by
    killed writers, and the ``.tmp-old-*`` leftovers of a replacement); returns how many."""
    parent = Path(parent)
    if not parent.is_dir():
        return 0
    removed = 0
    for tmp in parent.glob(f"{TEMP_FOLDER_PREFIX}*"):
        if not _writer_alive(tmp):
            shutil.rmtree(tmp, ignore_errors=True)
            removed += 1
    return removed
