"""SHA-256 of data files, read once per change of the file.

A sequence read from files is identified by its content (`bench.experiment.config.data_fingerprint`), so that
data copied to another machine, checked out again or touched keeps its run ids, and data rewritten in place
gets new ones. Hashing a 300-frame capture (about 5 GB) takes seconds, so each digest is kept in the cache folder
(``$DPCBENCH_CACHE`` or ``~/.cache/dpcbench/standins``, as the stand-ins', under ``file-digests/``), keyed by the
file's resolved path, size and modification time: a file is read again only when one of them changes. A cache
entry that cannot be read or written costs a re-read, never a wrong digest: the key covers everything a rewrite
changes short of a same-size, same-mtime edit (`cp -p` of other bytes onto it), and the entry stores its key.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from dpcbench.bench.core.atomic import atomic_write_text
from dpcbench.bench.data.standins.cache import cache_dir

_CHUNK = 1 << 20


def _key(path: Path) -> str:
    stat = path.stat()
    return f"{path.resolve()}|{stat.st_size}|{stat.st_mtime_ns}"


def _entry(key: str) -> Path:
    return cache_dir() / "file-digests" / f"{hashlib.sha256(key.encode()).hexdigest()[:32]}.txt"


def file_sha256(path: str | Path) -> str:
    """Hex SHA-256 of the file's bytes (from the cache when the file is unchanged since it was last read)."""
    path = Path(path)
    key = _key(path)
    entry = _entry(key)
    try:
        stored_key, digest = entry.read_text().split("\n")[:2]
        if stored_key == key and len(digest) == 64:
            return digest
    except (OSError, ValueError):
        pass
    sha = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(_CHUNK), b""):
            sha.update(chunk)
    digest = sha.hexdigest()
    try:
        atomic_write_text(entry, f"{key}\n{digest}\n")
    except OSError:  # a read-only cache folder: the digest is still right, it is just not kept
        pass
    return digest


def file_digests(files: list[Path]) -> list[tuple[str, str]]:
    """(name, `file_sha256`) of each file, in order: what identifies a set of data files."""
    return [(Path(p).name, file_sha256(p)) for p in files]
