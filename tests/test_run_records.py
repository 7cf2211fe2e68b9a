"""Run records (bench.records.RunRecord): what the store's `runs` table holds about a run, built in one
place for finished and failed runs, its columns the store's; rows round trip; and what a sweep stores
is what main stored (tests/data/run_rows_golden.json, written by main's code before RunRecord)."""

from __future__ import annotations

import json
import os
import re
import sqlite3
from pathlib import Path

from dpcbench.bench.config import parse_config
from dpcbench.bench.runner import run_experiment
from dpcbench.bench.store import ResultsStore
from tests import runner_fixtures as helpers

REPO = Path(__file__).resolve().parents[1]
GOLDEN = REPO / "tests" / "data" / "run_rows_golden.json"
_ISO = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00$")


def _sweep(tmp_path: Path) -> Path:
    """A done and a failed run of a 2-frame sphere folder through the runner (serial); the store's path.
    The frames' modification times are fixed, so the data fingerprint and with it the run ids are too."""
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=300)
    for frame in seq.iterdir():
        os.utime(frame, ns=(1_700_000_000_000_000_000, 1_700_000_000_000_000_000))
    cfg = {"experiment": {"name": "t", "timeout_s": 120}, "sequences": [{"path": str(seq), "label": "sphere"}],
           "holes": [{"generator": "test-ball", "params": {"radius": 0.3}, "seed": 1}],
           "methods": [{"name": "test-identity", "params": {"shift": 0.5}}, {"name": "test-raises"}],
           "metrics": {"names": ["gpsnr_d1"], "peaks": ["intrinsic"], "scopes": ["frame"]}}
    store = ResultsStore(tmp_path / "s.sqlite")
    run_experiment(parse_config(cfg).expand(), store, executor="serial", quiet=True)
    return store.path


def stored_rows(tmp_path: Path) -> dict:
    """The runs table of `_sweep`'s store with what varies between sweeps masked: the folder, the git
    commit, times and the machine (their SQLite types are kept), the traceback's frames (its last line kept)."""
    path = _sweep(tmp_path)
    conn = sqlite3.connect(path)
    try:
        schema = conn.execute("SELECT sql FROM sqlite_master WHERE name = 'runs'").fetchone()[0]
        cur = conn.execute("SELECT * FROM runs ORDER BY method")
        columns = [d[0] for d in cur.description]
        rows = [dict(zip(columns, r)) for r in cur.fetchall()]
        types = conn.execute("SELECT " + ", ".join(f"typeof({c})" for c in columns) + " FROM runs ORDER BY method")
        types = [dict(zip(columns, t)) for t in types.fetchall()]
    finally:
        conn.close()
    commit = rows[0]["code_version"]
    out = []
    for row in rows:
        masked = {}
        for column, value in row.items():
            if isinstance(value, str):
                value = value.replace(str(tmp_path.resolve()), "<tmp>").replace(str(tmp_path), "<tmp>")
                value = value.replace(commit, "<commit>")
            if column in ("created_at", "finished_at"):
                assert _ISO.match(value), value
                value = "<iso time>"
            elif column in ("wall_time_s", "cpu_time_s", "peak_mem_mb") and value is not None:
                value = "<number>"
            elif column == "env":
                env = json.loads(value)
                if "traceback" in env:
                    env["traceback"] = env["traceback"].strip().splitlines()[-1]
                else:  # the machine, packages and versions vary; which facts are recorded does not
                    env = {k: (v if k in ("frames_reused", "d2_normals", "git_commit") else "<machine>")
                           for k, v in env.items()}
                value = env
            masked[column] = value
        out.append(masked)
    return {"schema": schema, "columns": columns, "rows": out, "types": types}


def test_a_sweep_stores_what_main_stored(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    monkeypatch.chdir(REPO)  # workers import tests.runner_fixtures from the repo root
    assert stored_rows(tmp_path) == json.loads(GOLDEN.read_text())


if __name__ == "__main__":  # writes the golden file: python -m tests.test_run_records (only on main's code)
    import tempfile

    helpers.register_global()
    with tempfile.TemporaryDirectory() as tmp:
        GOLDEN.write_text(json.dumps(stored_rows(Path(tmp)), indent=1, sort_keys=True) + "\n")
