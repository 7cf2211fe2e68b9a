"""Where commands write, checked before any work is done.

Rules, for every command:

- an output path must be writable: not an existing file where a folder is expected (or a folder
  where a file is), not under a file, not in a folder that cannot be written;
- a command never replaces an existing file that dpcbench did not write, unless the user passes
  ``--overwrite``; a file dpcbench wrote (recorded in the output ledger with its size and
  modification time, and unchanged since) is replaced freely, so rerunning a command into its own
  output is not an error;
- a command never writes into the input sequence: not into its folder, not over one of its files,
  and never a non-PLY file over a ``.ply``;
- a sequence written into a folder that already holds other ``.ply`` frames would mix with them
  (a reader takes every ``.ply`` of a folder), so it is refused;
- ground truth is never replaced without ``--overwrite``: in a damage output (a folder holding a
  ``masks.npz`` or a ``holes.json`` written by ``dpcbench damage``), no file is replaced by any
  command without it, even one dpcbench wrote (`is_ground_truth`);
- nothing is written through a symbolic link leading out of the output folder
  (`bench.core.atomic.check_within`);
- a folder output (a sequence, a report) is written into a hidden staging folder and swapped in
  whole (`Outputs.staged`, `bench.core.atomic.staged_output`): it appears whole or not at all, one
  writer at a time.

The output ledger is ``written-outputs.jsonl`` in the dpcbench cache folder (`bench.data.standins.cache.cache_dir`):
one JSON line per file written, ``{"path", "size", "mtime_ns"}``. Losing it is harmless: the next
run into the same place then asks for ``--overwrite``.

Every refusal is a `UserError` naming the option, the path and what to do. The paths a command
checked are kept in `CLAIMED`, so that an `OSError` while writing them (disk full) is reported by
the CLI as one line, and any other OSError as the bug it is.
"""

from __future__ import annotations

import errno
import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

from dpcbench.bench.core.atomic import check_within, is_temporary, staged_output
from dpcbench.bench.core.errors import UserError

#: output paths (files and folders, resolved) claimed by the running command
CLAIMED: list[Path] = []
LEDGER_NAME = "written-outputs.jsonl"


def ledger_path() -> Path:
    from dpcbench.bench.data.standins.cache import cache_dir

    return cache_dir() / LEDGER_NAME


def _stat(path: Path) -> tuple[int, int]:
    st = path.stat()
    return st.st_size, st.st_mtime_ns


def _ledger() -> dict[str, tuple[int, int]]:
    path = ledger_path()
    entries: dict[str, tuple[int, int]] = {}
    if not path.is_file():
        return entries
    for line in path.read_text(errors="replace").splitlines():
        try:
            item = json.loads(line)
            entries[item["path"]] = (int(item["size"]), int(item["mtime_ns"]))
        except (ValueError, KeyError, TypeError):  # a torn line from a killed writer: skip it
            continue
    return entries


def written_by_dpcbench(path: str | os.PathLike, ledger: dict | None = None) -> bool:
    """True when dpcbench wrote ``path`` and it has not changed since (size and mtime as recorded)."""
    path = Path(path)
    if not path.is_file():
        return False
    ledger = _ledger() if ledger is None else ledger
    return ledger.get(str(path.resolve())) == _stat(path)


def record_written(paths) -> None:
    """Add files just written to the ledger (best effort: an unwritable cache only costs --overwrite later)."""
    lines = []
    for p in paths:
        p = Path(p)
        if p.is_file():
            size, mtime = _stat(p)
            lines.append(json.dumps({"path": str(p.resolve()), "size": size, "mtime_ns": mtime}) + "\n")
    if not lines:
        return
    ledger = ledger_path()
    try:
        ledger.parent.mkdir(parents=True, exist_ok=True)
        with open(ledger, "a") as fh:
            fh.write("".join(lines))
    except OSError:
        pass


def is_ground_truth(folder: str | os.PathLike) -> bool:
    """True for a damage output: ``folder`` holds a ``masks.npz``, or a ``holes.json`` whose record names a
    ``generator`` (written by ``dpcbench damage``; one from ``detect-holes`` names a ``detector``)."""
    folder = Path(folder)
    if (folder / "masks.npz").exists():
        return True
    record = folder / "holes.json"
    if not record.is_file():
        return False
    try:
        with open(record, "rb") as fh:
            head = fh.read(1 << 16)
        return b'"generator"' in head
    except OSError:
        return False


#: staging folder (resolved) -> the output it becomes, while a command writes it (`Outputs.staged`)
STAGES: dict[Path, Path] = {}
#: errors of a full or failing device: about the output being written even when they carry no file name
_DEVICE_ERRORS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS}


def claimed_target(err: OSError) -> Path | None:
    """The claimed output an OSError is about (its filename lies in or is one, or in the staging folder
    of one), else None. A full disk (ENOSPC, EDQUOT, EFBIG, EROFS) with no file name (numpy's and zlib's
    writes) is about the last output claimed."""
    names = [n for n in (err.filename, getattr(err, "filename2", None)) if n]
    for name in names:
        try:
            path = Path(os.fsdecode(name)).resolve()
        except (OSError, ValueError):
            continue
        for stage, out in STAGES.items():
            if path == stage or stage in path.parents:
                return out
        for claimed in CLAIMED:
            if path == claimed or claimed in path.parents:
                return claimed
    if not names and err.errno in _DEVICE_ERRORS and CLAIMED:
        return CLAIMED[-1]
    return None


def _within(path: Path, root: Path) -> bool:
    return path == root or root in path.parents


def user_path(text) -> Path:
    """``Path(text)`` with a leading ``~`` or ``~user`` expanded; a ``~name`` that names no user (Python
    raises RuntimeError) is taken literally, as the shell does."""
    try:
        return Path(text).expanduser()
    except RuntimeError:
        return Path(text)


def _resolvable(path: Path, option: str, shown) -> Path:
    """``path.resolve()``; UserError for a symbolic link loop (or a path too deep to resolve)."""
    try:
        return path.resolve()
    except (RuntimeError, OSError) as err:  # Python < 3.13 raises RuntimeError for a link loop
        raise UserError(f"{option} {shown}: cannot be resolved ({err}); remove the link loop or choose another "
                        "path") from None


def _existing_ancestor(path: Path) -> Path:
    probe = path
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    return probe


def _check_writable_folder(folder: Path, option: str, shown) -> None:
    """Prove that files can be written in ``folder``, or, when it does not exist yet, that it can be
    created (a probe file in its nearest existing ancestor). Nothing is left behind."""
    base = _existing_ancestor(folder)
    try:
        fd, probe = tempfile.mkstemp(prefix=".dpcbench-probe-", dir=base)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise UserError(f"{option} {shown}: cannot write in {base} ({err.strerror or err}); "
                        "choose a folder you can write to") from None


class Outputs:
    """The output checks of one command.

    overwrite: the user passed ``--overwrite`` (replace files dpcbench did not write).
    inputs:    the input sources (folder, glob, file or dataset name) never to be written into.
    """

    def __init__(self, overwrite: bool = False, inputs=()):
        self.overwrite = overwrite
        self.input_dirs: set[Path] = set()
        self.input_files: set[Path] = set()
        for source in inputs:
            self._protect(source)
        self._ledger: dict[str, tuple[int, int]] | None = None

    # -- inputs -----------------------------------------------------------------------------
    def _protect(self, source) -> None:
        if source is None:
            return
        text = str(source)
        path = user_path(text)
        _resolvable(path, "input", text)
        if path.is_dir():
            self.input_dirs.add(path.resolve())
        elif path.is_file():
            self.input_files.add(path.resolve())
        elif any(ch in text for ch in "*?["):
            import glob

            for match in glob.glob(text):
                if Path(match).is_file():
                    self.input_files.add(Path(match).resolve())

    def _inside_input(self, target: Path) -> Path | None:
        for folder in self.input_dirs:
            if target == folder or folder in target.parents:
                return folder
        if target in self.input_files:
            return target
        return None

    def _ours(self, path: Path) -> bool:
        if self._ledger is None:
            self._ledger = _ledger()
        return written_by_dpcbench(path, self._ledger)

    def _refuse_foreign(self, paths: list[Path], option: str, shown) -> None:
        if self.overwrite:
            return
        truth = [p for p in paths if os.path.lexists(p) and is_ground_truth(p.parent)]
        if truth:
            names = ", ".join(p.name for p in truth[:3]) + (f" and {len(truth) - 3} more" if len(truth) > 3 else "")
            raise UserError(f"{option} {shown}: {truth[0].parent} is a damage output (the ground truth of a "
                            f"benchmark); writing here would replace {names}; choose another {option} or pass "
                            "--overwrite to replace them")
        foreign = [p for p in paths if p.exists() and not self._ours(p)]
        if foreign:
            names = ", ".join(p.name for p in foreign[:3])
            names += f" and {len(foreign) - 3} more" if len(foreign) > 3 else ""
            raise UserError(f"{option} {shown}: would replace {len(foreign)} existing file(s) that dpcbench did not "
                            f"write ({names}); choose another {option} or pass --overwrite to replace them")

    # -- checks -----------------------------------------------------------------------------
    def file(self, path, option: str = "--out", suffixes: tuple[str, ...] = ()) -> Path:
        """Check an output file path (nothing is created). Returns the path."""
        shown = path
        path = user_path(path)
        _resolvable(path, option, shown)
        if suffixes and path.suffix.lower() not in suffixes:
            raise UserError(f"{option} {shown}: the output is a {'/'.join(suffixes)} file; give a path ending in "
                            f"{suffixes[0]}")
        if path.is_dir():
            raise UserError(f"{option} {shown}: is a folder; give the path of the file to write")
        base = _existing_ancestor(path.parent)
        if base.exists() and not base.is_dir():
            raise UserError(f"{option} {shown}: {base} is a file, not a folder; choose an output path outside it")
        target = path.resolve()
        hit = self._inside_input(target)
        if hit is not None:
            raise UserError(f"{option} {shown}: lies in the input {hit}; the input is never overwritten: "
                            "choose an output outside it")
        if path.is_symlink() and not _within(target, path.parent.resolve()):
            raise UserError(f"{option} {shown}: is a symbolic link to {target}, outside its folder; dpcbench never "
                            "writes through such a link: remove it or choose another path")
        self._refuse_foreign([path], option, shown)
        _check_writable_folder(path.parent, option, shown)
        CLAIMED.append(target)
        return path

    def folder(self, path, option: str = "--out", names=(), sequence: bool = False) -> Path:
        """Check an output folder into which ``names`` (file names) will be written (nothing is created).

        sequence: the folder receives PLY frames, so other ``.ply`` files in it are refused.
        """
        shown = path
        path = user_path(path)
        _resolvable(path, option, shown)
        if path.exists() and not path.is_dir():
            raise UserError(f"{option} {shown}: exists and is a file, not a folder; choose a folder path")
        base = _existing_ancestor(path)
        if not base.is_dir():
            raise UserError(f"{option} {shown}: {base} is a file, not a folder; choose an output path outside it")
        target = path.resolve()
        hit = self._inside_input(target)
        if hit is not None:
            raise UserError(f"{option} {shown}: is (or lies in) the input {hit}; the input is never overwritten: "
                            "choose another output folder")
        targets = [path / n for n in names]
        if path.is_dir():
            for t in targets:
                check_within(t, path, option)
        for item in self.input_files:
            if item in {t.resolve() for t in targets} or (sequence and item.parent == target):
                raise UserError(f"{option} {shown}: holds the input file {item.name}; the input is never overwritten "
                                "(and new frames beside it would join its sequence): choose another output folder")
        if sequence and path.is_dir() and not self.overwrite and is_ground_truth(path):
            raise UserError(f"{option} {shown}: is a damage output (the ground truth of a benchmark); new frames there "
                            "would join its sequence: choose another output folder or pass --overwrite")
        if sequence and path.is_dir():
            planned = {t.name for t in targets}
            stale = sorted(p.name for p in path.iterdir() if p.suffix.lower() == ".ply" and p.name not in planned
                           and not is_temporary(p.name))  # a killed writer's leftovers are no frames
            if stale:
                raise UserError(f"{option} {shown}: already holds {len(stale)} other .ply frame(s) "
                                f"({', '.join(stale[:3])}{' ...' if len(stale) > 3 else ''}) that would mix with "
                                "the new sequence; choose an empty or new folder")
        self._refuse_foreign(targets, option, shown)
        _check_writable_folder(path, option, shown)
        CLAIMED.append(target)
        return path

    @contextmanager
    def staged(self, out, option: str = "--out"):
        """``with guard.staged(out) as folder:`` write everything into ``folder`` (a hidden staging folder
        beside ``out``); on leaving the block it becomes ``out`` in one rename (`bench.core.atomic.staged_output`:
        older entries it does not replace are kept; one writer at a time). Refused, with ``out`` left as it
        was, when a file would replace one dpcbench did not write or ground truth (checked again under the
        lock, just before the swap). An exception inside the block leaves ``out`` as it was. The files
        written are added to the ledger."""
        out = Path(os.path.realpath(user_path(out)))
        written: list[Path] = []

        def last_checks(rel):
            targets = [out / r for r in rel]
            self._refuse_foreign(targets, option, out)
            for target in targets:
                base = _existing_ancestor(target.parent)
                if not base.is_dir():
                    raise UserError(f"{option} {out}: {base} is a file where the output needs a folder; move it "
                                    "or choose another output folder")
            written.extend(targets)

        with staged_output(out, option, before_publish=last_checks) as folder:
            STAGES[folder.resolve()] = out
            yield folder
        STAGES.pop(folder.resolve(), None)
        record_written(written)
