"""Where a report's runs were computed, and what that means for its scores.

Every run records the instruction set it computed with (``env["isa"]``, `bench.core.isa.describe`) and the code
version it ran (``+dirty`` when the checkout had modified tracked files). Three methods' fills turn a last-bit change
of numpy's or OpenBLAS's kernels into another fill, so their scores move with the machine alone unless the runs were
pinned (`bench.core.isa`). `computed_with_notes` says so beside a report's figures; `dpcbench margins`, `dpcbench
report` and `reproduce-paper`'s REPORT.md (`reports.provenance_markdown`) print its notes.
"""

from __future__ import annotations

import pandas as pd

#: methods whose fills turn a last-bit change of numpy's or OpenBLAS's kernels into another fill (`bench.core.isa`):
#: those whose runs' mean D1 moved by more than 0.1 dB between unpinned and pinned (up to 3 dB; lozes-pde and
#: temporal-copy by at most 0.02, none and meshlab not at all)
ISA_SENSITIVE = ("temporal-fusion", "temporal-graph", "fu-nonlocal")
#: how far that moved them, as measured: the 546 runs of the temporal-fusion margins presets unpinned (AVX-512) and
#: pinned on one machine, `experiments/run_diff.py` (results/README.md, `temporal-fusion-57-pinned/`)
ISA_MOVE = "a run's mean D1 by up to 3.2 dB, a frame's by up to 6.4 dB"
#: what to do about unpinned or mixed runs, for every command that runs experiments
RERUN_PINNED = ("rerun pinned (`pin_isa = true` in the experiment's [experiment] table, or `--pin-isa` on "
                "`dpcbench run` and `dpcbench reproduce-paper`)")


def env_isa(env_text) -> str:
    """The run's instruction set as `bench.core.isa.describe` recorded it in ``env["isa"]``; "not recorded" for
    runs stored before it was (or whose env is not JSON)."""
    from dpcbench.bench.experiment.records import run_env

    isa = run_env(env_text).get("isa")
    return isa if isinstance(isa, str) and isa else "not recorded"


def computed_with_table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per run of ``runs`` (a store's `runs_frame`, or a part of it): its registry method (``method_name``),
    its instruction set (``isa``, `env_isa`) and its code version (``code_version``, "?" where not recorded): the
    table `computed_with_notes` reads."""
    runs = runs.drop_duplicates("run_id")
    return pd.DataFrame({"method_name": runs["method"].astype(str).to_numpy(),
                         "isa": [env_isa(text) for text in runs["env"]],
                         "code_version": [v if isinstance(v, str) and v else "?" for v in runs["code_version"]]})


def computed_with_notes(table: pd.DataFrame) -> list[str]:
    """Where the runs of ``table`` (columns ``method_name``, ``isa``, ``code_version``; `computed_with_table`) were
    computed: each instruction set with its run count, and the number of runs made from a checkout with modified
    tracked files (code version ``+dirty``: what they ran may not be the committed code of their method version). A
    warning when runs of an `ISA_SENSITIVE` method were made with more than one instruction set, and one when any
    were not pinned: those methods' scores move with the instruction set alone (`ISA_MOVE`), so a margin or a
    verdict may partly be the machine's. [] for no runs."""
    if table.empty:
        return []
    counts = table["isa"].value_counts()
    sets = "; ".join(f"{isa} on {n} runs" for isa, n in sorted(counts.items(), key=lambda x: (-x[1], x[0])))
    notes = [f"instruction sets of the runs read: {sets}"]
    dirty = table[table["code_version"].str.endswith("+dirty")]
    if len(dirty):
        methods = ", ".join(f"{m} {n}" for m, n in sorted(dirty["method_name"].value_counts().items()))
        notes.append(f"code: {len(dirty)} of {len(table)} runs read were made from a checkout with modified files "
                     f"(+dirty: {methods}); their method version may not name the code they ran; rerun them from a "
                     "clean checkout (--force)")
    sensitive = table[table["method_name"].isin(ISA_SENSITIVE)]
    names = ", ".join(sorted(set(sensitive["method_name"])))
    if sensitive["isa"].nunique() > 1:
        notes.append(f"instruction sets MIXED for {names} ({sensitive['isa'].nunique()} sets): their scores move with "
                     f"the instruction set alone ({ISA_MOVE}), so compare rows made on one machine, or "
                     f"{RERUN_PINNED}")
    loose = ~sensitive["isa"].str.contains("; pinned (", regex=False)
    if loose.any():
        notes.append(f"{int(loose.sum())} of the {len(sensitive)} runs of {names} were not computed pinned: their "
                     f"scores are this machine's ({ISA_MOVE} on another instruction set); {RERUN_PINNED} for scores "
                     "any x86-64 machine with AVX2 reproduces")
    return notes
