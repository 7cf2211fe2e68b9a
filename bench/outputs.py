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
  (a reader takes every ``.ply`` of a folder), so it is refused.

The output ledger is ``written-outputs.jsonl`` in the dpcbench cache folder (`bench.standins.cache.cache_dir`):
one JSON line per file written, ``{"path", "size", "mtime_ns"}``. Losing it is harmless: the next
run into the same place then asks for ``--overwrite``.

Every refusal is a `UserError` naming the option, the path and what to do. The paths a command
checked are kept in `CLAIMED`, so that an `OSError` while writing them (disk full) is reported by
the CLI as one line, and any other OSError as the bug it is.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from dpcbench.bench.errors import UserError

#: output paths (files and folders, resolved) claimed by the running command
CLAIMED: list[Path] = []
LEDGER_NAME = "written-outputs.jsonl"


def ledger_path() -> Path:
    from dpcbench.bench.standins.cache import cache_dir

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


def claimed_target(err: OSError) -> Path | None:
    """The claimed output an OSError is about (its filename lies in or is one), else None."""
    for name in (err.filename, getattr(err, "filename2", None)):
        if not name:
            continue
        try:
            path = Path(os.fsdecode(name)).resolve()
        except (OSError, ValueError):
            continue
        for claimed in CLAIMED:
            if path == claimed or claimed in path.parents:
                return claimed
    return None


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
        self._ledger = None

    # -- inputs -----------------------------------------------------------------------------
    def _protect(self, source) -> None:
        if source is None:
            return
        text = str(source)
        path = Path(text).expanduser()
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
        path = Path(path).expanduser()
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
        self._refuse_foreign([path], option, shown)
        _check_writable_folder(path.parent, option, shown)
        CLAIMED.append(target)
        return path

    def folder(self, path, option: str = "--out", names=(), sequence: bool = False) -> Path:
        """Check an output folder into which ``names`` (file names) will be written (nothing is created).

        sequence: the folder receives PLY frames, so other ``.ply`` files in it are refused.
        """
        shown = path
        path = Path(path).expanduser()
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
        for item in self.input_files:
            if item in {t.resolve() for t in targets} or (sequence and item.parent == target):
                raise UserError(f"{option} {shown}: holds the input file {item.name}; the input is never overwritten "
                                "(and new frames beside it would join its sequence): choose another output folder")
        if sequence and path.is_dir():
            planned = {t.name for t in targets}
            stale = sorted(p.name for p in path.iterdir() if p.suffix.lower() == ".ply" and p.name not in planned)
            if stale:
                raise UserError(f"{option} {shown}: already holds {len(stale)} other .ply frame(s) "
                                f"({', '.join(stale[:3])}{' ...' if len(stale) > 3 else ''}) that would mix with "
                                "the new sequence; choose an empty or new folder")
        self._refuse_foreign(targets, option, shown)
        _check_writable_folder(path, option, shown)
        CLAIMED.append(target)
        return path

    def commit(self, staged: Path, out: Path, option: str = "--out") -> list[Path]:
        """Move every file of the staging folder ``staged`` to the same place under ``out`` (after
        checking that none replaces a file dpcbench did not write); removes ``staged``."""
        files = [p for p in sorted(staged.rglob("*")) if p.is_file()]
        targets = [out / p.relative_to(staged) for p in files]
        try:
            self._refuse_foreign(targets, option, out)
            for target in targets:
                base = _existing_ancestor(target.parent)
                if not base.is_dir():
                    raise UserError(f"{option} {out}: {base} is a file where the output needs a folder; move it "
                                    "or choose another output folder")
            for src, dst in zip(files, targets):
                dst.parent.mkdir(parents=True, exist_ok=True)
                os.replace(src, dst)
        finally:
            shutil.rmtree(staged, ignore_errors=True)
        record_written(targets)
        return targets

    @contextmanager
    def staged(self, out: Path, option: str = "--out"):
        """``with guard.staged(out) as folder:`` write everything into ``folder`` (hidden, inside
        ``out``); on leaving the block the files are moved into ``out`` by `commit` (refused, with
        nothing moved, when one would replace a file dpcbench did not write). An exception inside
        the block leaves ``out`` as it was."""
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        folder = Path(tempfile.mkdtemp(prefix=".dpcbench-staging-", dir=out))
        try:
            yield folder
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        self.commit(folder, out, option)
