"""Canonical JSON text: the one place where dpcbench turns values into comparable, hashable text.

Two forms, both with sorted keys and compact separators (``","`` and ``":"``), so equal values give
equal bytes whatever the dict order:

- `canonical_json`: normalised first (whole floats written as ints, tuples as lists, keys as
  strings, anything else as ``str``), so 1 and 1.0 hash alike. What run ids hash (`bench.experiment.config`).
- `sorted_json`: the value as it is (1.0 stays ``1.0``), optionally with ``default=str`` for values
  JSON cannot write. What the results store keeps as a run's parameters, spec and environment, and
  what reports compare that text with.
"""

from __future__ import annotations

import hashlib
import json
import math

_SEPARATORS = (",", ":")


def normalize(value):
    """Canonical form for hashing: whole floats -> int, tuples -> lists, dict keys as strings (sorted by
    the JSON writer), non-finite floats as text, anything else as ``str``."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, float):
        if math.isfinite(value) and value == int(value) and abs(value) < 2**53:
            return int(value)
        return float(value) if math.isfinite(value) else str(value)  # float(): a numpy float as a Python one
    if isinstance(value, int):
        return int(value)
    if isinstance(value, dict):
        return {str(k): normalize(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [normalize(v) for v in value]
    return str(value)


def canonical_json(value) -> str:
    """`normalize`d ``value`` as JSON with sorted keys and compact separators."""
    return json.dumps(normalize(value), sort_keys=True, separators=_SEPARATORS)


def stable_hash(value) -> str:
    """First 16 hex digits of SHA-256 of the canonical JSON of ``value``."""
    return hashlib.sha256(canonical_json(value).encode()).hexdigest()[:16]


def sorted_json(value, *, stringify: bool = False) -> str:
    """``value`` as JSON with sorted keys and compact separators, not normalised; ``stringify``
    writes what JSON cannot (a numpy scalar, a path) as its ``str`` instead of raising TypeError."""
    return json.dumps(value, sort_keys=True, separators=_SEPARATORS, default=str if stringify else None)
