"""`bench.reporting.computed_with`: where a report's runs were computed, and the warnings it prints."""


def test_computed_with_notes_count_instruction_sets_and_dirty_runs_and_flags_unpinned_or_mixed_greedy_fills():
    """The runs' instruction sets with their counts; runs from a modified checkout counted per method; warnings only
    where temporal-fusion, temporal-graph or fu-nonlocal (whose fills move with the last bits) ran unpinned or with
    more than one set."""
    import pandas as pd

    from dpcbench.bench.reporting.computed_with import computed_with_notes, env_isa

    assert env_isa('{"isa": "x86_64; numpy dispatch up to AVX2; unpinned"}') == "x86_64; numpy dispatch up to AVX2; unpinned"
    assert env_isa(None) == env_isa("{not json") == env_isa('{"git_commit": "abc"}') == "not recorded"
    a, b = "x86_64; numpy dispatch up to AVX512_ICL; unpinned", "x86_64; numpy dispatch up to AVX2; unpinned"
    pinned = "x86_64; numpy dispatch up to X86_V3; pinned (OPENBLAS_CORETYPE=Haswell)"
    table = pd.DataFrame({"method_name": ["lozes-pde", "fu-nonlocal", "fu-nonlocal", "none"],
                          "isa": [a, pinned, pinned, b], "code_version": ["c1", "c1", "c2+dirty", "c1"]})
    notes = computed_with_notes(table)
    assert notes[0] == f"instruction sets of the runs read: {pinned} on 2 runs; {b} on 1 runs; {a} on 1 runs"
    assert notes[1].startswith("code: 1 of 4 runs read were made from a checkout with modified files (+dirty: "
                               "fu-nonlocal 1)")
    assert len(notes) == 2  # fu-nonlocal pinned on one set; the others unpinned on two move nothing: no warning
    unpinned = computed_with_notes(table.assign(isa=[pinned, a, a, pinned], code_version="c1"))
    assert len(unpinned) == 2 and unpinned[1].startswith("2 of the 2 runs of fu-nonlocal were not computed pinned")
    mixed = computed_with_notes(table.assign(isa=[a, pinned, a, a], code_version="c1"))
    assert len(mixed) == 3 and mixed[1].startswith("instruction sets MIXED for fu-nonlocal (2 sets)")
    assert mixed[2].startswith("1 of the 2 runs of fu-nonlocal were not computed pinned")


def test_computed_with_table_reads_the_runs_env_and_code_version_once_per_run():
    """One row per run (a run listed under two experiments counts once), its method, the instruction set its env
    recorded ("not recorded" for a missing or damaged env) and its code version ("?" when not recorded)."""
    import json

    import pandas as pd

    from dpcbench.bench.reporting.computed_with import computed_with_table

    runs = pd.DataFrame({"run_id": ["a", "a", "b", "c"], "method": ["none", "none", "fu-nonlocal", "lozes-pde"],
                         "env": [json.dumps({"isa": "x86_64; unpinned"})] * 2 + ["{broken", None],
                         "code_version": ["c1", "c1", None, "c2+dirty"]})
    table = computed_with_table(runs)
    assert table.to_dict("list") == {"method_name": ["none", "fu-nonlocal", "lozes-pde"],
                                     "isa": ["x86_64; unpinned", "not recorded", "not recorded"],
                                     "code_version": ["c1", "?", "c2+dirty"]}
