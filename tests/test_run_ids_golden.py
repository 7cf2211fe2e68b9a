"""Golden run ids: the run_id and inpaint_key of representative runs, pinned as literal hex.

The ids name stored runs and their on-disk frame folders, so a change to how a run spec is built,
normalised or hashed (bench.experiment.config, bench.core.canonical) must not move them. The values were computed on
main before the run records were typed (branch records); they change only when a version that is
hashed into a run changes (a method's or generator's version, the metrics' versions, the embedded
datasets' version), never by refactoring.
"""

from __future__ import annotations

import pytest

from dpcbench.bench.experiment.config import parse_config

_METRICS = {"names": ["gpsnr_d1", "gpsnr_d2"], "peaks": ["intrinsic", 1023], "scopes": ["frame", "holes"],
            "region_margin": 0.5, "temporal_consistency": True}


def _config(**experiment) -> dict:
    return {
        "experiment": {"name": "golden", "description": "presentation only", **experiment},
        "sequences": [{"name": "human", "params": {"size": "tiny"}, "frames": 3, "label": "Human (tiny)"}],
        "holes": [{"generator": "region", "params": {"preset": "medium", "count": 2, "coherent": True},
                   "seeds": [0, 7]}],
        "methods": [{"name": "temporal-fusion"},
                    {"name": "temporal-graph", "params": {"beta": 0.25, "cube_size": 16.0}, "label": "TG"}],
        "metrics": _METRICS,
    }


def _runs(**experiment) -> dict:
    runs = parse_config(_config(**experiment), source="golden").expand()
    return {(r.method["name"], r.holes["seed"], r.protocol["regions"]): (r.run_id, r.inpaint_key) for r in runs}


GOLDEN = {
    # a stand-in with region holes and temporal-fusion (defaults; temporal-fusion version 43)
    ("temporal-fusion", 0, "given"): ("657b4e44e251ca2a", "69c2718eea4ee3dd"),
    # the same run with a second seed
    ("temporal-fusion", 7, "given"): ("2fc0c3b9203b1665", "3f2ec9dc47dd5c31"),
    # a method with parameters
    ("temporal-graph", 0, "given"): ("18c35ec2c5eb570b", "2ffeafcc90183ee4"),
    # detected regions: the detector's parameters and version are hashed as well
    ("temporal-graph", 7, "detected"): ("dd9fac738cdb2358", "4457fe3e67d9ad73"),
}


@pytest.mark.parametrize("key", sorted(GOLDEN))
def test_run_ids_are_the_golden_ones(key):
    regions = key[2]
    runs = _runs(regions=regions, **({"detection": {"min_points": 5}} if regions == "detected" else {}))
    assert runs[key] == GOLDEN[key]


def test_presentation_does_not_move_the_ids():
    # labels, descriptions and the data role are not hashed (bench.experiment.config's docstring)
    cfg = _config()
    cfg["experiment"].update(description="another", data_role="tuning")
    cfg["sequences"][0]["label"] = "another label"
    cfg["methods"][1]["label"] = "another"
    runs = {(r.method["name"], r.holes["seed"], r.protocol["regions"]): (r.run_id, r.inpaint_key)
            for r in parse_config(cfg, source="golden").expand()}
    assert runs[("temporal-fusion", 0, "given")] == GOLDEN[("temporal-fusion", 0, "given")]
