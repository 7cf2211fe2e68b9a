"""Atomic writes: a file (or a folder) appears whole under its final name or not at all.

Everything dpcbench writes for others to read (PLY frames, summaries, figures, pages, cache entries,
run folders, worker outcomes) goes through here: the content is written to a temporary sibling in
the same folder (so the final rename never crosses a filesystem) and renamed over the target with
`os.replace`, which POSIX and Windows make atomic for a single name. A writer killed half-way
leaves only a hidden temporary file; a reader never sees half a file (`is_temporary` names what
readers skip). Files get the mode the umask gives (``0o666 & ~umask``), not mkstemp's 0600.

Outputs of several files (a sequence folder, a report) go through `staged_output`: written into a
hidden sibling folder ``.<name>.dpcbench-stage-<pid>-<random>``, then swapped with the output
folder in one rename (``renameat2(RENAME_EXCHANGE)`` where the kernel has it, else two renames), so
the output appears whole or not at all and an old output stays until the new one is complete. One
writer at a time per output folder: a lock file ``.<name>.dpcbench-lock`` beside it (``flock``,
released by the kernel when the writer dies); under the lock, every staging folder of that output is
a killed writer's leftover and is removed. `check_within` refuses a target reached through a
symbolic link that leads out of the output folder.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from dpcbench.bench.core.errors import UserError

#: the infix of `staged_output`'s hidden staging folders and the suffix of its lock files
STAGE_TAG = ".dpcbench-stage-"
LOCK_SUFFIX = ".dpcbench-lock"
_TEMP_FILE = re.compile(r"\.tmp(\.|$)")


def is_temporary(name: str) -> bool:
    """True for names readers must skip: hidden (``.*``: temporary files, staging folders, locks) or
    temporary (``*.tmp.*``, ``*.tmp``)."""
    return name.startswith(".") or bool(_TEMP_FILE.search(name))


def current_umask() -> int:
    """The process umask, read without changing it (Linux: /proc/self/status; else set and restore)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _is_within(path: Path, root: Path) -> bool:
    return path == root or root in path.parents


def check_within(path: str | os.PathLike, root: str | os.PathLike, option: str = "--out") -> Path:
    """Refuse (UserError) a ``path`` under ``root`` that, or one of whose folders below ``root``, is a
    symbolic link leading out of ``root``: a write there would land outside the output folder
    (possibly over the input). Links that stay inside ``root`` are allowed. Returns ``Path(path)``."""
    path, root = Path(path), Path(root)
    root_abs = Path(os.path.abspath(root))
    root_real = root_abs.resolve()
    target = Path(os.path.abspath(path))
    try:
        parts = target.relative_to(root_abs).parts
    except ValueError:
        parts = None
    if parts is None:
        if not _is_within(target.resolve(), root_real):
            raise UserError(f"{option} {root}: {path} lies outside the output folder; nothing is written outside it")
        return path
    probe = root_abs
    for part in parts:
        probe = probe / part
        if probe.is_symlink():
            real = probe.resolve()
            if not _is_within(real, root_real):
                raise UserError(f"{option} {root}: {probe} is a symbolic link to {real}, outside the output folder; "
                                "dpcbench never writes through such a link: remove it or choose another output folder")
    return path


@contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str | None = None) -> Iterator[Path]:
    """``with atomic_path(out) as tmp: write(tmp)``: on leaving the block ``tmp`` is renamed to ``out``.

    ``out`` itself is replaced, never written through (a symbolic link there is replaced by the
    file). ``tmp`` is a fresh, unique name beside ``out`` (``.<name>.<random>.tmp<suffix>``); ``suffix``
    defaults to ``out``'s own suffix, so writers that choose the format by extension (matplotlib's
    savefig, numpy's savez) see the right one. The parent folder is created. On an exception inside
    the block the temporary file is removed and ``out`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix if suffix is None else suffix}",
                                dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~current_umask())  # the mode a plain open() would give, not mkstemp's 0600
    except OSError:
        pass
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


# -- staged outputs: a folder of files appears whole ----------------------------------------------
@contextmanager
def output_lock(out: str | os.PathLike, option: str = "--out") -> Iterator[None]:
    """Hold the lock of output folder ``out`` (``.<name>.dpcbench-lock`` beside it, or inside it when
    its parent cannot be written) for the block; UserError at once when another process holds it.
    The kernel releases a killed holder's lock; the file is removed on leaving."""
    import fcntl

    out = Path(os.path.abspath(out))
    lock = out.parent / f".{out.name}{LOCK_SUFFIX}"
    if not os.access(out.parent, os.W_OK) and out.is_dir():
        lock = out / LOCK_SUFFIX
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise UserError(f"{option} {out}: another dpcbench command (process {holder}) is writing this output "
                            "now; wait for it to finish or choose another output folder") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino  # not a lock file removed by its last holder
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        try:
            os.unlink(lock)
        except OSError:
            pass
        os.close(fd)


def _stages_of(out: Path) -> list[Path]:
    return [p for p in out.parent.glob(f".{glob_escape(out.name)}{STAGE_TAG}*") if p.is_dir()]


def remove_stale_stages(parent: str | os.PathLike) -> int:
    """Remove the `staged_output` staging folders in ``parent`` whose writer process is gone (the pid in
    their name, ``.<out>.dpcbench-stage-<pid>-<random>``, runs no more); returns how many. Folders of
    live writers and the ``-old-`` leftovers of a swap (removed under their output's lock) are kept."""
    removed = 0
    for stage in Path(parent).glob(f".*{STAGE_TAG}*"):
        pid = stage.name.rsplit(STAGE_TAG, 1)[-1].split("-")[0]
        if not stage.is_dir() or not pid.isdigit():
            continue
        try:
            os.kill(int(pid), 0)
            continue  # alive (or another user's process)
        except ProcessLookupError:
            pass
        except PermissionError:
            continue
        shutil.rmtree(stage, ignore_errors=True)
        removed += 1
    return removed


def glob_escape(name: str) -> str:
    import glob

    return glob.escape(name)


def _carry(old: Path, new: Path) -> None:
    """Give ``new`` every entry of ``old`` it lacks (hard links, else copies; links stay links); folders
    present in both are merged the same way."""
    for entry in old.iterdir():
        dst = new / entry.name
        if entry.is_dir() and not entry.is_symlink():
            if dst.is_dir() and not dst.is_symlink():
                _carry(entry, dst)
            elif not os.path.lexists(dst):
                shutil.copytree(entry, dst, symlinks=True, copy_function=_link_or_copy)
        elif not os.path.lexists(dst):
            if entry.is_symlink():
                os.symlink(os.readlink(entry), dst)
            else:
                _link_or_copy(entry, dst)


def _link_or_copy(src, dst) -> None:
    try:
        os.link(src, dst, follow_symlinks=False)
    except OSError:
        shutil.copy2(src, dst, follow_symlinks=False)


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step (Linux ``renameat2(RENAME_EXCHANGE)``); False where unsupported."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    at_fdcwd, rename_exchange = -100, 2
    return renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


def _publish(stage: Path, out: Path) -> None:
    """Make the staged folder the output: carry the old output's other entries over, then swap."""
    if not out.exists():
        os.replace(stage, out)
        return
    _carry(out, stage)
    try:
        os.chmod(stage, out.stat().st_mode & 0o7777)  # the output folder keeps its mode
    except OSError:
        pass
    if _exchange(stage, out):
        shutil.rmtree(stage, ignore_errors=True)  # now the old output
        return
    trash = out.parent / f".{out.name}{STAGE_TAG}old-{uuid.uuid4().hex[:8]}"
    os.replace(out, trash)
    os.replace(stage, out)
    shutil.rmtree(trash, ignore_errors=True)


def _move_in(stage: Path, out: Path) -> None:
    """Fallback where the output cannot be swapped (it is the working folder, or its parent is not
    writable): the staged files are renamed into ``out`` one by one, record files (.json) last."""
    files = sorted((p for p in stage.rglob("*") if p.is_file()), key=lambda p: (p.suffix == ".json", str(p)))
    for src in files:
        dst = out / src.relative_to(stage)
        dst.parent.mkdir(parents=True, exist_ok=True)
        os.replace(src, dst)


@contextmanager
def staged_output(out: str | os.PathLike, option: str = "--out", *, before_publish=None) -> Iterator[Path]:
    """``with staged_output(out) as stage: write(stage)``: on leaving the block the files written
    into ``stage`` become ``out``'s, all in one rename (see the module doc); entries of an older
    ``out`` that the new output does not replace are kept. An exception (or a kill) inside the block
    leaves ``out`` as it was. ``before_publish(relative_paths)`` runs under the lock just before the
    swap (the last checks: a refusal there leaves ``out`` as it was). Holds `output_lock` throughout."""
    out = Path(os.path.abspath(out))
    out.parent.mkdir(parents=True, exist_ok=True)
    with output_lock(out, option):
        for stale in _stages_of(out):  # under the lock: left by a killed writer
            shutil.rmtree(stale, ignore_errors=True)
        remove_stale_stages(out.parent)
        cwd = Path(os.getcwd()).resolve() if os.path.exists(".") else None
        swap = os.access(out.parent, os.W_OK) and not (out.exists() and cwd is not None
                                                         and _is_within(cwd, out.resolve()))
        if swap:
            stage = out.parent / f".{out.name}{STAGE_TAG}{os.getpid()}-{uuid.uuid4().hex[:8]}"
        else:
            out.mkdir(parents=True, exist_ok=True)
            for stale in out.glob(f"{STAGE_TAG}*"):
                shutil.rmtree(stale, ignore_errors=True)
            stage = out / f"{STAGE_TAG}{os.getpid()}-{uuid.uuid4().hex[:8]}"
        stage.mkdir()
        try:
            yield stage
            rel = [p.relative_to(stage) for p in sorted(stage.rglob("*")) if p.is_file()]
            if out.exists():
                for r in rel:
                    check_within(out / r, out, option)
            if before_publish is not None:
                before_publish(rel)
            if swap:
                _publish(stage, out)
            else:
                _move_in(stage, out)
        finally:
            if stage.exists():
                shutil.rmtree(stage, ignore_errors=True)
