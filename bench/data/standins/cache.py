"""On-disk cache of generated stand-in frames, so a large variant is generated once.

Location: ``$DPCBENCH_CACHE`` if set, else ``~/.cache/dpcbench/standins``. One ``.npz`` file per
frame, named by a SHA-256 of the generator name, its version and every parameter (JSON, sorted keys),
plus the frame index. Writes go to a temporary file in the same folder and are renamed into place, so
concurrent readers never see a partial file; a file that fails to load is regenerated.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from dpcbench.bench.core.atomic import atomic_path


def cache_dir() -> Path:
    """The cache folder (not created here)."""
    env = os.environ.get("DPCBENCH_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "dpcbench" / "standins"


def cache_key(generator: str, version: int, params: dict, frame: int) -> str:
    """Hex SHA-256 of (generator, version, params, frame); params must be JSON-serializable."""
    text = json.dumps({"generator": generator, "version": version, "params": params, "frame": int(frame)},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def cache_path(key: str, generator: str) -> Path:
    return cache_dir() / generator / f"{key[:32]}.npz"


def load_cached(key: str, generator: str) -> dict[str, np.ndarray] | None:
    """The arrays stored under ``key``, or None when absent or unreadable."""
    path = cache_path(key, generator)
    if not path.is_file():
        return None
    try:
        with np.load(path) as data:
            if str(data["key"]) != key:
                return None
            return {name: data[name] for name in data.files if name != "key"}
    except Exception:  # a damaged cache entry is regenerated, never fatal
        return None


def store_cached(key: str, generator: str, arrays: dict[str, np.ndarray]) -> Path | None:
    """Write ``arrays`` atomically; returns the path, or None when the cache folder is not writable
    (generation still works, it just is not cached)."""
    path = cache_path(key, generator)
    try:
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            # numpy's stub lets **kwds reach its `allow_pickle: bool`; these keys are array names
            np.savez(fh, key=np.array(key), **arrays)  # type: ignore[arg-type]
    except OSError:
        return None
    return path
