"""bench.core.canonical: the one canonical-JSON helper. Every former copy (config's hashing, the store's JSON
columns, compare's and paper's parameter keys, margins' row identities) now calls it; the expected
texts below are what each copy wrote on main before it was replaced, byte for byte."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dpcbench.bench.core import canonical
from dpcbench.bench.experiment import config
from dpcbench.bench.experiment.records import COLUMNS, RunRecord
from dpcbench.bench.reporting import margins, paper
from dpcbench.bench.results import compare

MIXED = {"b": 1.0, "a": [1, 2.5, (3, 4)], "c": {"z": None, "y": True, "x": "é"}, 2: "int key"}
FLOATS = {"radius": 0.1, "count": 2, "nested": {"k": [0.30000000000000004, -0.0, 1e-300, 2.0**60, float("inf")]}}
NUMPY_FLOATS = {"radius": np.float64(0.1), "whole": np.float64(3.0)}
UNWRITABLE = {"seed": np.int64(3), "where": Path("/tmp/x"), "ratio": np.float32(0.5)}

def _stored(value) -> str:
    """The text the store writes for a JSON column (was bench._stored)."""
    return RunRecord.from_facts("r", {"holes_params": value}, "done").to_row()[COLUMNS.index("holes_params")]


PLAIN_FLOATS = '{"count":2,"nested":{"k":[0.30000000000000004,-0.0,1e-300,1.152921504606847e+18,Infinity]},"radius":0.1}'


def test_hashing_form_is_mains():
    assert config.canonical_json(MIXED) == '{"2":"int key","a":[1,2.5,[3,4]],"b":1,"c":{"x":"\\u00e9","y":true,"z":null}}'
    assert config.stable_hash(MIXED) == "1ed53e7a26808a50"
    assert config.canonical_json(FLOATS) == (
        '{"count":2,"nested":{"k":[0.30000000000000004,0,1e-300,1.152921504606847e+18,"inf"]},"radius":0.1}')
    assert config.stable_hash(FLOATS) == "f6e614cf9334e267"
    assert config.stable_hash({}) == "44136fa355b3678a"
    assert config.canonical_json(UNWRITABLE) == '{"ratio":"0.5","seed":"3","where":"/tmp/x"}'
    assert config.canonical_json is canonical.canonical_json and config.stable_hash is canonical.stable_hash


def test_numpy_floats_hash_like_python_floats():
    # main raised ValueError here (the repr of a numpy 2 float is "np.float64(0.1)")
    assert canonical.canonical_json(NUMPY_FLOATS) == canonical.canonical_json({"radius": 0.1, "whole": 3}) == (
        '{"radius":0.1,"whole":3}')


@pytest.mark.parametrize("site", [_stored, margins._canonical, compare._canonical_json, paper._params_key])
def test_stored_form_is_mains(site):
    assert site(FLOATS) == PLAIN_FLOATS
    assert site(NUMPY_FLOATS) == '{"radius":0.1,"whole":3.0}'  # not normalised: 3.0 stays 3.0
    assert site({}) == "{}"
    with pytest.raises(TypeError):  # an int key among str keys cannot be sorted
        site(MIXED)


@pytest.mark.parametrize("site", [_stored, margins._canonical])
def test_stringifying_sites_write_what_json_cannot(site):
    assert site(UNWRITABLE) == '{"ratio":"0.5","seed":"3","where":"/tmp/x"}'


def test_parameter_keys_of_json_text_are_mains():
    text = json.dumps({"b": 1.0, "a": {"y": 2, "x": 1}})
    for site in (compare._canonical_json, paper._params_key):
        assert site(text) == '{"a":{"x":1,"y":2},"b":1.0}'
        assert site(None) == site("") == "{}"
    assert compare._canonical_json(float("nan")) == "{}"
    assert paper._params_key(float("nan")) == "NaN"


def test_sorted_json_raises_without_stringify():
    with pytest.raises(TypeError):
        canonical.sorted_json(UNWRITABLE)
    assert canonical.sorted_json({"b": [1.0], "a": None}) == '{"a":null,"b":[1.0]}'
