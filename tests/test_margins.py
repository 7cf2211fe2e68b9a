"""The held-out discipline: data roles in experiment configs, `dpcbench margins`, the oracle fill."""

from __future__ import annotations

from pathlib import Path

import pytest

from dpcbench.bench.config import ConfigError, load_config, parse_config
from tests import runner_fixtures as helpers

PRESETS = Path(__file__).resolve().parents[1] / "bench" / "presets"


@pytest.fixture
def seq_dir(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    return helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=200)


def _config(seq_dir, **experiment):
    return {
        "experiment": {"name": "t", "timeout_s": 60, **experiment},
        "sequences": [{"path": str(seq_dir), "frames": 2}],
        "holes": [{"generator": "test-ball", "params": {"radius": 0.2}, "seeds": [0]}],
        "methods": [{"name": "test-identity"}],
        "metrics": {"names": ["gpsnr_d1"], "peaks": ["intrinsic"], "scopes": ["frame"]},
    }


# -- the config key ------------------------------------------------------------------------------
def test_data_role_is_parsed_recorded_and_not_hashed(seq_dir):
    plain = parse_config(_config(seq_dir)).expand()
    tuning = parse_config(_config(seq_dir, data_role="tuning")).expand()
    heldout = parse_config(_config(seq_dir, data_role="heldout", holds_out="tune")).expand()
    assert [r.data_role for r in plain] == [None]
    assert [(r.data_role, r.holds_out) for r in tuning] == [("tuning", None)]
    assert [(r.data_role, r.holds_out) for r in heldout] == [("heldout", "tune")]
    # the role is recorded in the spec a run stores, and never changes an id (cached runs stay cached)
    assert heldout[0].to_dict()["data_role"] == "heldout" and heldout[0].to_dict()["holds_out"] == "tune"
    assert plain[0].run_id == tuning[0].run_id == heldout[0].run_id


@pytest.mark.parametrize("experiment, message", [
    ({"data_role": "validation"}, "experiment.data_role: expected one of tuning, heldout, got 'validation'"),
    ({"data_role": "heldout"}, "experiment.holds_out: a held-out experiment names the tuning experiment"),
    ({"data_role": "heldout", "holds_out": "t"}, "experiment.holds_out: a held-out experiment names"),
    ({"data_role": "tuning", "holds_out": "x"}, "experiment.holds_out: only with data_role = \"heldout\""),
    ({"holds_out": "x"}, "experiment.holds_out: only with data_role"),
])
def test_bad_data_role_is_refused_in_one_line(seq_dir, experiment, message):
    with pytest.raises(ConfigError) as err:
        parse_config(_config(seq_dir, **experiment))
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_every_fusion_preset_declares_its_role():
    roles = {}
    for path in sorted(PRESETS.glob("temporal-fusion-*.toml")):
        cfg = load_config(path)
        roles[cfg.name] = (cfg.data_role, cfg.holds_out)
    assert roles.pop("fusion-targets") == ("tuning", None)
    assert roles and all(role == ("heldout", "fusion-targets") for role in roles.values()), roles


def test_unknown_role_on_the_command_line_exits_2(tmp_path, seq_dir, capsys):
    from dpcbench.bench.cli import main

    config = tmp_path / "c.toml"
    config.write_text(f'[experiment]\nname = "t"\ndata_role = "train"\n[[sequences]]\npath = "{seq_dir}"\n'
                      '[[holes]]\ngenerator = "test-ball"\n[[methods]]\nname = "test-identity"\n')
    assert main(["run", str(config), "--dry-run", "--store", str(tmp_path / "s.sqlite")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "experiment.data_role: expected one of tuning, heldout" in err
