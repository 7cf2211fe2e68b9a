"""The results store: one SQLite database (stdlib `sqlite3`) that runs, reports and the dashboard share.

Location: a parameter everywhere; the default is ``$DPCBENCH_STORE`` or, when unset,
``$XDG_CACHE_HOME/dpcbench/results.sqlite`` (``~/.cache/dpcbench/results.sqlite``): never the source tree.

Schema (version `SCHEMA_VERSION`)::

    schema_version(version INTEGER)
    runs(run_id TEXT PRIMARY KEY, status TEXT 'done'|'failed', error TEXT,
         sequence, holes, holes_params (JSON), seed, method, method_params (JSON), method_version,
         code_version (git commit), spec (JSON), wall_time_s, cpu_time_s, peak_mem_mb, env (JSON),
         created_at, finished_at, output_dir)        -- the fields of bench.experiment.records.RunRecord
    experiment_runs(experiment TEXT, run_id TEXT)      -- a run may belong to several experiments
    results(run_id, frame INTEGER, metric, scope, peak, value REAL)
        PRIMARY KEY (run_id, frame, metric, scope, peak)  -- frame = -1 for sequence-level values
    run_claims(run_id TEXT PRIMARY KEY, token, host, pid INTEGER, started, claimed_at REAL)
        -- runs a sweep is computing now (`bench.execution.claims`); created by any writable open, not versioned:
        -- a store without it reads the same, and older dpcbench ignore it

``wall_time_s`` and ``cpu_time_s`` cover the same span of the run (`bench.execution.worker`): wall-clock seconds
and CPU seconds (user + system, all threads of the worker process and its waited-for children). On a
loaded machine the wall time measures the load as much as the run; the CPU time barely moves with it.
``cpu_time_s`` is NULL for runs recorded before schema version 2 (and for runs whose CPU time could
not be measured).

Schema versions and migration: version 1 had no ``cpu_time_s``. Opening a version-1 store for
writing migrates it in place (one transaction: ``ALTER TABLE runs ADD COLUMN cpu_time_s REAL``, then
version 2; every row is kept, their CPU time NULL). A read-only open never writes: it reads a
version-1 store as it is and shows its CPU times as NULL. A store newer than this code is refused.

Write discipline (what makes a killed run harmless and a rerun idempotent):
- Only the driver process writes (workers send their results back to it); WAL mode and a busy
  timeout still let readers (reports, the dashboard) and a second driver work concurrently.
- `record_run` writes a run's results *and* its 'done' status in ONE transaction, after deleting
  any earlier rows of that run id: the store holds either all of a run's rows or none, and a rerun
  replaces rather than duplicates. A run killed before `record_run` leaves no trace.
- `record_failure` writes the 'failed' status and message (and drops stale results) in one transaction.
- Both drop the run's claim in that transaction; `claim_runs` claims in one ``BEGIN IMMEDIATE``
  transaction, so two sweeps claiming at once get disjoint runs.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sqlite3
import time
from contextlib import contextmanager
from pathlib import Path

import pandas as pd

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.execution.claims import ClaimHolder
from dpcbench.bench.experiment.records import COLUMNS as RECORD_COLUMNS
from dpcbench.bench.experiment.records import RunRecord, now_iso  # noqa: F401 - now_iso re-exported

SCHEMA_VERSION = 2
#: schema versions this code can open (older ones are migrated on a writable open, see the module docstring)
READABLE_SCHEMA_VERSIONS = (1, 2)

#: columns of `ResultsStore.results_frame`, in order
RESULT_COLUMNS = [
    "run_id", "experiment", "sequence", "holes", "holes_params", "seed", "method", "method_params",
    "method_version", "code_version", "frame", "metric", "scope", "peak", "value", "created_at",
]
#: the ``runs`` table's columns, in order: the fields of `bench.experiment.records.RunRecord`
_RUN_TABLE_COLUMNS = list(RECORD_COLUMNS)
#: columns of `ResultsStore.runs_frame`, in order: the table's, with the experiment after the run id
RUN_COLUMNS = [_RUN_TABLE_COLUMNS[0], "experiment", *_RUN_TABLE_COLUMNS[1:]]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS runs (
    run_id TEXT PRIMARY KEY,
    status TEXT NOT NULL CHECK (status IN ('done', 'failed')),
    error TEXT,
    sequence TEXT, holes TEXT, holes_params TEXT, seed INTEGER,
    method TEXT, method_params TEXT, method_version TEXT, code_version TEXT,
    spec TEXT NOT NULL,
    wall_time_s REAL, cpu_time_s REAL, peak_mem_mb REAL, env TEXT,
    created_at TEXT NOT NULL, finished_at TEXT, output_dir TEXT
);
CREATE TABLE IF NOT EXISTS experiment_runs (
    experiment TEXT NOT NULL,
    run_id TEXT NOT NULL,
    PRIMARY KEY (experiment, run_id)
);
CREATE TABLE IF NOT EXISTS results (
    run_id TEXT NOT NULL,
    frame INTEGER NOT NULL,
    metric TEXT NOT NULL,
    scope TEXT NOT NULL,
    peak TEXT NOT NULL DEFAULT '',
    value REAL,
    PRIMARY KEY (run_id, frame, metric, scope, peak)
);
CREATE INDEX IF NOT EXISTS results_run ON results (run_id);
"""

_CLAIMS_SCHEMA = """
CREATE TABLE IF NOT EXISTS run_claims (
    run_id TEXT PRIMARY KEY,
    token TEXT NOT NULL, host TEXT NOT NULL, pid INTEGER NOT NULL, started TEXT NOT NULL,
    claimed_at REAL NOT NULL
);
"""


def default_store_path() -> Path:
    """``$DPCBENCH_STORE``, else ``$XDG_CACHE_HOME/dpcbench/results.sqlite`` (``~/.cache/...``)."""
    env = os.environ.get("DPCBENCH_STORE")
    if env:
        return Path(env).expanduser()
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return cache / "dpcbench" / "results.sqlite"


def _uri(path: Path, **query: str) -> str:
    """The SQLite URI of ``path`` (absolute, every character but ``/`` percent-escaped, so that ``#``,
    ``?`` and ``%`` in a file name name that file) with the ``query`` parameters."""
    from urllib.parse import quote

    text = quote(os.path.abspath(path), safe="/")
    return f"file:{text}?" + "&".join(f"{k}={v}" for k, v in query.items())


def _connect_readonly(path: Path, timeout_s: float) -> sqlite3.Connection:
    """A read-only connection. A WAL store in a folder this process cannot write cannot get its
    shared-memory file; with no journal left beside it (``-wal`` missing or empty), nothing can be
    unmerged and no one can be writing, so it is opened ``immutable``."""
    try:
        conn = sqlite3.connect(_uri(path, mode="ro"), uri=True, timeout=timeout_s)
        conn.execute("SELECT 1 FROM sqlite_master LIMIT 1").fetchall()
        return conn
    except sqlite3.OperationalError:
        wal = Path(f"{path}-wal")
        if os.access(path.parent, os.W_OK) or (wal.exists() and wal.stat().st_size > 0):
            raise
    return sqlite3.connect(_uri(path, mode="ro", immutable="1"), uri=True, timeout=timeout_s)


def _corrupt_message(path: Path, err: Exception) -> str:
    return (
        f"{path}: the results store is damaged or not a dpcbench store ({type(err).__name__}: {err}); nothing was "
        f"read from it; move it aside (mv {path} {path}.bad) and rerun `dpcbench run`, which rebuilds the results "
        "from the run folders' stored frames, or pass another --store PATH"
    )


@dataclasses.dataclass
class Claimed:
    """What `ResultsStore.claim_runs` made of a list of run ids, each in one of three."""

    #: claimed now for the caller, to compute
    mine: list[str] = dataclasses.field(default_factory=list)
    #: held by another live sweep: run id -> its holder
    held: dict[str, ClaimHolder] = dataclasses.field(default_factory=dict)
    #: stored and kept: run id -> 'done' | 'failed'
    stored: dict[str, str] = dataclasses.field(default_factory=dict)


class ResultsStore:
    """The SQLite results store at ``path`` (created with its folder on first write).

    ``readonly=True`` never creates or alters anything (for reports and the dashboard): a missing
    file is then an error. Every error about an unusable file is a ValueError whose message says
    what to do.
    """

    def __init__(self, path: str | os.PathLike | None = None, *, readonly: bool = False, timeout_s: float = 60.0,
                 verify: bool = False):
        from dpcbench.bench.data.outputs import _resolvable, user_path

        self.path = user_path(path) if path is not None else default_store_path()
        _resolvable(self.path, "--store", self.path)  # a symbolic link loop
        self.readonly = readonly
        self.timeout_s = timeout_s
        #: the schema version of the file as opened (1 only for an old store opened read-only)
        self.schema_version = SCHEMA_VERSION
        if self.path.is_dir():
            raise UserError(f"{self.path}: is a folder; the store is a file: pass e.g. {self.path / 'results.sqlite'}")
        if readonly and not self.path.is_file():
            raise UserError(f"{self.path}: no results store there; run `dpcbench run CONFIG --store {self.path}` first")
        if not readonly:
            self.check_path(self.path)
            self.path.parent.mkdir(parents=True, exist_ok=True)
        if verify and self.path.is_file() and self.path.stat().st_size:
            self.verify()  # before _init writes anything (journal mode) into a damaged file
        self._init()

    @staticmethod
    def check_path(path: Path) -> None:
        """UserError unless a store can be created or written at ``path`` (nothing is created):
        not under a file, not a folder, in a folder that can be written (SQLite's journal goes beside)."""
        from dpcbench.bench.data.outputs import _check_writable_folder, _existing_ancestor

        base = _existing_ancestor(path.parent)
        if not base.is_dir():
            raise UserError(f"--store {path}: {base} is a file, not a folder; give a store path outside it")
        if path.exists() and not path.is_file():
            raise UserError(f"--store {path}: is not a regular file; give the path of a results store")
        if path.is_file() and not os.access(path, os.R_OK | os.W_OK):
            raise UserError(f"--store {path}: the file cannot be written (read-only); make it writable "
                            f"(chmod u+w {path}) or pass another --store")
        _check_writable_folder(path.parent, "--store", path)

    def verify(self) -> ResultsStore:
        """``PRAGMA quick_check``: refuse (UserError) a damaged store before anything is read from or
        written to it, with the way out. Returns the store."""
        try:
            conn = _connect_readonly(self.path, self.timeout_s)
            try:
                rows = [str(r[0]) for r in conn.execute("PRAGMA quick_check").fetchall()]
            finally:
                conn.close()
        except sqlite3.OperationalError as err:  # cannot be opened (permissions, a journal it cannot reach)
            raise UserError(f"{self.path}: cannot open the results store ({err}); check that it and its folder "
                            "can be read (and its -wal/-shm files, if any), or copy it to a folder you can write") from None
        except sqlite3.DatabaseError as err:  # not even the header reads
            raise UserError(_corrupt_message(self.path, err)) from None
        rows = [line for row in rows for line in row.splitlines() if line and not line.startswith("***")] or rows
        if rows != ["ok"]:
            first = "; ".join(str(r) for r in rows[:2]) + (f" (and {len(rows) - 2} more)" if len(rows) > 2 else "")
            raise UserError(
                f"{self.path}: the results store is damaged (SQLite quick_check: {first}); nothing was read from "
                f"it; move it aside (mv {self.path} {self.path}.bad) and rerun `dpcbench run`, which rebuilds the "
                "results from the run folders' stored frames, or pass another --store PATH")
        return self

    # -- connection ------------------------------------------------------------------------
    def _connect(self) -> sqlite3.Connection:
        if self.readonly:
            conn = _connect_readonly(self.path, self.timeout_s)
        else:
            conn = sqlite3.connect(str(self.path), timeout=self.timeout_s)
        conn.execute(f"PRAGMA busy_timeout = {int(self.timeout_s * 1000)}")
        return conn

    @contextmanager
    def _conn(self):
        try:
            conn = self._connect()
        except sqlite3.Error as err:
            raise UserError(_corrupt_message(self.path, err)) from err
        try:
            yield conn
        except pd.errors.DatabaseError as err:  # pandas wraps the sqlite3 error of a damaged file
            if "malformed" in str(err) or "not a database" in str(err):
                raise UserError(_corrupt_message(self.path, err)) from err
            raise
        except sqlite3.DatabaseError as err:
            # "file is not a database" / "database disk image is malformed" mean a damaged file;
            # other errors (locked, programming errors) pass through unchanged.
            if type(err) is sqlite3.DatabaseError or "malformed" in str(err) or "not a database" in str(err):
                raise UserError(_corrupt_message(self.path, err)) from err
            raise
        finally:
            conn.close()

    def _init(self) -> None:
        with self._conn() as conn:
            tables = {row[0] for row in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
            if not tables:
                if self.readonly:
                    raise UserError(f"{self.path}: the file is empty, not a results store; run `dpcbench run` first")
                conn.execute("PRAGMA journal_mode = WAL")
                with conn:
                    conn.executescript(_SCHEMA + _CLAIMS_SCHEMA)
                    conn.execute("INSERT INTO schema_version (version) VALUES (?)", (SCHEMA_VERSION,))
                return
            if "schema_version" not in tables or not {"runs", "results"} <= tables:
                raise UserError(
                    f"{self.path}: this SQLite file is not a dpcbench results store (tables: {sorted(tables)}); "
                    "pass the store's path, or a new path to start one"
                )
            if "experiment_runs" not in tables:
                raise UserError(_corrupt_message(self.path, ValueError("the experiment_runs table is missing")))
            row = conn.execute("SELECT MAX(version) FROM schema_version").fetchone()
            if row[0] not in READABLE_SCHEMA_VERSIONS:
                raise UserError(
                    f"{self.path}: store schema version {row[0]}, this dpcbench reads versions "
                    f"{', '.join(map(str, READABLE_SCHEMA_VERSIONS))}; use a new --store path (or the dpcbench "
                    "version that wrote it)"
                )
            self.schema_version = int(row[0])
            if not self.readonly:
                conn.execute("PRAGMA journal_mode = WAL")
                if self.schema_version < SCHEMA_VERSION:
                    self._migrate(conn)
                if "run_claims" not in tables:
                    conn.executescript(_CLAIMS_SCHEMA)

    def _migrate(self, conn: sqlite3.Connection) -> None:
        """Bring an older store to `SCHEMA_VERSION` in one transaction; a second driver migrating at
        the same moment waits for the write lock (BEGIN IMMEDIATE), then finds nothing left to do."""
        conn.execute("BEGIN IMMEDIATE")
        try:
            version = int(conn.execute("SELECT MAX(version) FROM schema_version").fetchone()[0])
            if version < 2:
                columns = {r[1] for r in conn.execute("PRAGMA table_info(runs)")}
                if "cpu_time_s" not in columns:
                    conn.execute("ALTER TABLE runs ADD COLUMN cpu_time_s REAL")
            if version < SCHEMA_VERSION:
                conn.execute("DELETE FROM schema_version")
                conn.execute("INSERT INTO schema_version (version) VALUES (?)", (SCHEMA_VERSION,))
            conn.execute("COMMIT")
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        self.schema_version = SCHEMA_VERSION

    # -- writes ----------------------------------------------------------------------------
    @staticmethod
    def _record(run_id: str, record: RunRecord | dict, status: str, error: str | None) -> RunRecord:
        """``record`` as the `RunRecord` of run ``run_id`` with this status and error (a dict of run
        facts is completed by `RunRecord.from_facts`)."""
        if isinstance(record, RunRecord):
            return dataclasses.replace(record, run_id=run_id, status=status, error=error)
        return RunRecord.from_facts(run_id, record, status, error)

    def _write(self, run_id: str, record: RunRecord | dict, status: str, error: str | None, results: list[dict],
               experiments: list[str]) -> None:
        if self.readonly:
            raise UserError(f"{self.path}: opened read-only")
        rows = []
        for r in results:
            value = r["value"]
            value = None if value is None or (isinstance(value, float) and math.isnan(value)) else float(value)
            peak = r.get("peak")
            rows.append((run_id, int(r["frame"]), str(r["metric"]), str(r.get("scope", "frame")),
                         "" if peak is None else str(peak), value))
        with self._conn() as conn:
            with conn:  # one transaction: all of it or nothing
                conn.execute("DELETE FROM results WHERE run_id = ?", (run_id,))
                conn.execute("DELETE FROM run_claims WHERE run_id = ?", (run_id,))
                conn.execute(f"INSERT OR REPLACE INTO runs ({', '.join(_RUN_TABLE_COLUMNS)}) "
                             f"VALUES ({', '.join('?' * len(_RUN_TABLE_COLUMNS))})",
                             self._record(run_id, record, status, error).to_row())
                conn.executemany("INSERT OR REPLACE INTO results VALUES (?,?,?,?,?,?)", rows)
                conn.executemany("INSERT OR IGNORE INTO experiment_runs VALUES (?, ?)",
                                 [(e, run_id) for e in experiments if e])

    def record_run(self, run_id: str, record: RunRecord | dict, results: list[dict],
                   experiments: list[str] | tuple[str, ...] = ()) -> None:
        """Store a finished run and all its results in one transaction (replacing earlier rows).

        record:  a `bench.experiment.records.RunRecord`, or a dict of run facts (its fields but run_id, status and
                 error; missing ones filled by `RunRecord.from_facts`).
        results: dicts with frame (int, -1 = sequence level), metric, scope, peak ("" if none), value.
        """
        self._write(run_id, record, "done", None, results, list(experiments))

    def record_failure(self, run_id: str, record: RunRecord | dict, error: str,
                       experiments: list[str] | tuple[str, ...] = ()) -> None:
        """Mark a run failed with its message (stale results of that id are dropped)."""
        self._write(run_id, record, "failed", str(error), [], list(experiments))

    def add_to_experiment(self, experiment: str, run_ids: list[str]) -> None:
        """Make already-stored (cached) runs part of ``experiment`` too."""
        with self._conn() as conn:
            with conn:
                conn.executemany("INSERT OR IGNORE INTO experiment_runs VALUES (?, ?)",
                                 [(experiment, r) for r in run_ids])

    def claim_runs(self, run_ids: list[str], holder: ClaimHolder, *, redo_done: bool = False,
                   redo_failed: bool = False) -> Claimed:
        """Sort ``run_ids`` in one write transaction (so two sweeps doing this at once get disjoint
        runs) into those stored (kept as they are, unless ``redo_done`` / ``redo_failed`` asks for
        them again), those another live sweep holds, and the rest, which are now claimed for
        ``holder`` (claims of dead holders are taken over)."""
        if self.readonly:
            raise UserError(f"{self.path}: opened read-only")
        now = time.time()
        out = Claimed()
        with self._conn() as conn:
            conn.execute("BEGIN IMMEDIATE")  # the write lock first: no other sweep claims in between
            try:
                statuses = dict(conn.execute("SELECT run_id, status FROM runs").fetchall())
                claims = {r[0]: (ClaimHolder(*r[1:5]), r[5]) for r in conn.execute(
                    "SELECT run_id, token, host, pid, started, claimed_at FROM run_claims")}
                for run_id in dict.fromkeys(run_ids):
                    status = statuses.get(run_id)
                    if status is not None and not (redo_done if status == "done" else redo_failed):
                        out.stored[run_id] = status
                        continue
                    other, claimed_at = claims.get(run_id, (None, 0.0))
                    if other is not None and other.token != holder.token and other.is_alive(claimed_at, now):
                        out.held[run_id] = other
                    else:
                        out.mine.append(run_id)
                conn.executemany("INSERT OR REPLACE INTO run_claims VALUES (?, ?, ?, ?, ?, ?)",
                                 [(r, holder.token, holder.host, holder.pid, holder.started, now) for r in out.mine])
                conn.execute("COMMIT")
            except BaseException:
                conn.execute("ROLLBACK")
                raise
        return out

    def release_claims(self, holder: ClaimHolder) -> None:
        """Drop every claim ``holder`` still has (its sweep ends; runs it did not record go back)."""
        with self._conn() as conn:
            with conn:
                conn.execute("DELETE FROM run_claims WHERE token = ?", (holder.token,))

    def claims(self) -> dict[str, ClaimHolder]:
        """run id -> holder of every claim in the store, live or not."""
        with self._conn() as conn:
            tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
            if "run_claims" not in tables:
                return {}
            rows = conn.execute("SELECT run_id, token, host, pid, started FROM run_claims").fetchall()
        return {r[0]: ClaimHolder(*r[1:]) for r in rows}

    def delete_runs(self, run_ids: list[str]) -> None:
        with self._conn() as conn:
            with conn:
                for table in ("results", "experiment_runs", "runs"):
                    conn.executemany(f"DELETE FROM {table} WHERE run_id = ?", [(r,) for r in run_ids])

    # -- reads -----------------------------------------------------------------------------
    def statuses(self, run_ids: list[str] | None = None) -> dict[str, str]:
        """run_id -> 'done' | 'failed' for stored runs (optionally only those in ``run_ids``)."""
        with self._conn() as conn:
            rows = conn.execute("SELECT run_id, status FROM runs").fetchall()
        out = dict(rows)
        if run_ids is not None:
            wanted = set(run_ids)
            out = {k: v for k, v in out.items() if k in wanted}
        return out

    def experiments(self) -> list[str]:
        with self._conn() as conn:
            return [r[0] for r in conn.execute("SELECT DISTINCT experiment FROM experiment_runs ORDER BY experiment")]

    def _frame(self, sql: str, params: tuple) -> pd.DataFrame:
        with self._conn() as conn:
            return pd.read_sql_query(sql, conn, params=params)

    def results_frame(self, experiment: str | None = None, *, status: str = "done") -> pd.DataFrame:
        """The tidy long table, one row per (run, experiment, frame, metric, scope, peak).

        Columns `RESULT_COLUMNS`; ``experiment`` filters; runs in no experiment get experiment ''.
        Only results of runs whose status is ``status`` ('done'; failed runs have no results).
        """
        where = ["r.status = ?"]
        params: list = [status]
        if experiment is not None:
            where.append("e.experiment = ?")
            params.append(experiment)
        sql = f"""
            SELECT x.run_id, COALESCE(e.experiment, '') AS experiment, r.sequence, r.holes, r.holes_params,
                   r.seed, r.method, r.method_params, r.method_version, r.code_version,
                   x.frame, x.metric, x.scope, x.peak, x.value, r.finished_at AS created_at
            FROM results x JOIN runs r ON r.run_id = x.run_id
            LEFT JOIN experiment_runs e ON e.run_id = x.run_id
            WHERE {' AND '.join(where)}
            ORDER BY experiment, r.sequence, r.holes, r.seed, r.method, x.run_id, x.frame, x.metric, x.scope, x.peak
        """
        df = self._frame(sql, tuple(params))
        df["value"] = df["value"].astype(float)
        return df[RESULT_COLUMNS]

    def runs_frame(self, experiment: str | None = None) -> pd.DataFrame:
        """One row per (run, experiment): columns `RUN_COLUMNS` (spec/env as JSON text; cpu_time_s NaN
        where not recorded, e.g. every run of a version-1 store)."""
        params: tuple = ()
        where = ""
        # a version-1 store opened read-only has no such column: its runs show NULL
        cpu = "r.cpu_time_s" if self.schema_version >= 2 else "NULL"
        if experiment is not None:
            where = "WHERE e.experiment = ?"
            params = (experiment,)
        sql = f"""
            SELECT r.run_id, COALESCE(e.experiment, '') AS experiment, r.status, r.error, r.sequence, r.holes,
                   r.holes_params, r.seed, r.method, r.method_params, r.method_version, r.code_version, r.spec,
                   r.wall_time_s, {cpu} AS cpu_time_s, r.peak_mem_mb, r.env, r.created_at, r.finished_at,
                   r.output_dir
            FROM runs r LEFT JOIN experiment_runs e ON e.run_id = r.run_id {where}
            ORDER BY experiment, r.sequence, r.method, r.run_id
        """
        df = self._frame(sql, params)
        for column in ("wall_time_s", "cpu_time_s", "peak_mem_mb"):
            df[column] = pd.to_numeric(df[column], errors="coerce").astype(float)
        return df[RUN_COLUMNS]
