"""What the results store's ``runs`` table holds about a run: `RunRecord`, one row of it.

Its fields are the table's columns, in order (`COLUMNS`; `bench.results.store` derives its column lists from
them). `run_record` is the one place a record is made from a run spec, for a finished run
(`bench.execution.worker.execute_run`) and a failed one (`bench.execution.runner`) alike; `RunRecord.from_facts` makes one
from a loose dict of run facts (what a worker sends back, or a test writes), filling what is missing
as the store always did: empty parameters, spec and environment, the current time.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields
from datetime import datetime, timezone
from typing import Any, ClassVar

from dpcbench.bench.core.canonical import sorted_json

#: a run's outcome as stored
STATUSES = ("done", "failed")


def run_env(text) -> dict:
    """A run's ``env`` column (JSON text, `bench.execution.provenance.environment`) as a dict: {} where it is missing,
    empty, not JSON or not an object (runs stored before a key existed, a damaged row), so readers take ``.get``."""
    if not isinstance(text, str) or not text:
        return {}
    try:
        env = json.loads(text)
    except ValueError:
        return {}
    return env if isinstance(env, dict) else {}


def now_iso() -> str:
    """The current UTC time to the second, ISO 8601 (``2026-12-03T08:30:00+00:00``)."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


@dataclass(frozen=True)
class RunRecord:
    """One row of the ``runs`` table (field order = column order).

    ``holes_params``, ``method_params``, ``spec`` and ``env`` are dicts here and JSON text
    (`bench.core.canonical.sorted_json`, ``str`` for what JSON cannot write) in the table.
    """

    run_id: str
    status: str                         # "done" | "failed"
    error: str | None                   # the failure's one-line message (None when done)
    sequence: str | None                # the sequence's label
    holes: str | None                   # the hole generator's name
    holes_params: dict
    seed: int | None
    method: str | None                  # the method's registry name
    method_params: dict
    method_version: str | None
    code_version: str | None            # the git commit the run was made with
    spec: dict                          # `bench.experiment.config.RunSpec.to_dict()`
    wall_time_s: float | None
    cpu_time_s: float | None
    peak_mem_mb: float | None
    env: dict                           # environment facts (done) or the log path and traceback (failed)
    created_at: str
    finished_at: str
    output_dir: str | None              # the run folder (None for a failed run)

    #: the columns stored as JSON text
    JSON_COLUMNS: ClassVar[tuple[str, ...]] = ("holes_params", "method_params", "spec", "env")

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"run {self.run_id}: status {self.status!r}; expected one of {', '.join(STATUSES)}")

    @classmethod
    def from_facts(cls, run_id: str, facts: dict, status: str, error: str | None = None) -> RunRecord:
        """A record from a dict of run facts (any of the fields; the JSON ones as values), the rest as
        the store fills it: ``{}`` for parameters, spec and environment, now for missing times."""
        known = {f.name for f in fields(cls)} - {"run_id", "status", "error"}
        unknown = sorted(set(facts) - known)
        if unknown:
            raise ValueError(f"run {run_id}: unknown run facts {', '.join(unknown)}; known: {', '.join(sorted(known))}")
        values: dict[str, Any] = {name: facts.get(name) for name in known}
        for name in cls.JSON_COLUMNS:
            values[name] = facts.get(name, {})
        values["created_at"] = facts.get("created_at") or now_iso()
        values["finished_at"] = facts.get("finished_at") or now_iso()
        output_dir = facts.get("output_dir")
        values["output_dir"] = None if output_dir is None else str(output_dir)
        return cls(run_id=run_id, status=status, error=error, **values)

    def facts(self) -> dict:
        """The fields but run_id, status and error (what `from_facts` takes back)."""
        return {k: v for k, v in asdict(self).items() if k not in ("run_id", "status", "error")}

    def to_row(self) -> tuple:
        """The values of the table's columns, in `COLUMNS` order (JSON columns as text)."""
        return tuple(sorted_json(getattr(self, name), stringify=True) if name in self.JSON_COLUMNS
                     else getattr(self, name) for name in COLUMNS)

    @classmethod
    def from_row(cls, row) -> RunRecord:
        """The record of a row of the table: a sequence in `COLUMNS` order or a mapping by column."""
        values: dict[str, Any] = dict(row) if hasattr(row, "keys") else dict(zip(COLUMNS, row, strict=True))
        for name in cls.JSON_COLUMNS:
            text = values.get(name)
            values[name] = json.loads(text) if text else {}
        kwargs: dict[str, Any] = {name: values.get(name) for name in COLUMNS}
        return cls(**kwargs)


#: the ``runs`` table's columns, in order
COLUMNS: tuple[str, ...] = tuple(f.name for f in fields(RunRecord))


def run_record(spec, *, status: str, code_version: str | None, wall_time_s: float | None,
               cpu_time_s: float | None, env: dict, error: str | None = None, peak_mem_mb: float | None = None,
               created_at: str | None = None, finished_at: str | None = None,
               output_dir: str | None = None) -> RunRecord:
    """The record of a run of ``spec`` (a `bench.experiment.config.RunSpec`): what the spec says about the run (its
    sequence label, generator, method and their parameters, seed, method version, the spec itself) plus
    the outcome's facts; times missing are now."""
    facts = {
        "sequence": spec.sequence_label, "holes": spec.holes["generator"], "holes_params": spec.holes["params"],
        "seed": spec.holes["seed"], "method": spec.method["name"], "method_params": spec.method["params"],
        "method_version": spec.versions["method"], "code_version": code_version, "spec": spec.to_dict(),
        "wall_time_s": wall_time_s, "cpu_time_s": cpu_time_s, "peak_mem_mb": peak_mem_mb, "env": env,
        "created_at": created_at, "finished_at": finished_at, "output_dir": output_dir,
    }
    return RunRecord.from_facts(spec.run_id, facts, status, error)
