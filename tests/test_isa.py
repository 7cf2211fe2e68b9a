"""bench.core.isa: the pin is .ci/pinned-isa's, reaches the workers, and `compare` names each side's machine and ISA."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from dpcbench.bench.cli import main as cli_main
from dpcbench.bench.core import isa
from dpcbench.bench.results.store import ResultsStore

ROOT = Path(__file__).resolve().parents[1]

PINNED = """
[experiment]
name = "pinned"
pin_isa = true

[[sequences]]
name = "human"
params = { size = "tiny" }
frames = 2

[[holes]]
generator = "region"
params = { preset = "medium" }
seed = 0

[[methods]]
name = "none"

[metrics]
names = ["gpsnr_d1"]
peaks = ["intrinsic"]
scopes = ["frame"]
"""


def test_pin_environment_is_the_ci_scripts():
    if not (ROOT / ".venv" / "bin" / "python").exists():
        pytest.skip(".ci/pinned-isa needs the repository's .venv")
    out = subprocess.run([str(ROOT / ".ci" / "pinned-isa"), "env"], capture_output=True, text=True, check=True,
                         env={k: v for k, v in os.environ.items() if k not in isa.PIN_VARIABLES}).stdout
    script = dict(line.split("=", 1) for line in out.splitlines() if line.split("=", 1)[0] in isa.PIN_VARIABLES)
    assert isa.pin_environment() == script


def test_a_pinned_experiment_runs_its_workers_pinned(tmp_path, monkeypatch, capsys):
    for var in isa.PIN_VARIABLES:  # restored after the test: `dpcbench run` sets them for its workers
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    config = tmp_path / "pinned.toml"
    config.write_text(PINNED)
    store = tmp_path / "s.sqlite"
    assert cli_main(["run", str(config), "--store", str(store), "--quiet", "--executor", "serial"]) == 0
    assert "pin_isa = true" in capsys.readouterr().err
    assert not any(var in os.environ for var in isa.PIN_VARIABLES)  # the caller's environment is given back
    env = json.loads(ResultsStore(store, readonly=True).runs_frame()["env"].iloc[0])
    expected = isa.pin_environment()
    if "NPY_DISABLE_CPU_FEATURES" in expected:
        assert "numpy dispatch up to X86_V3; pinned" in env["isa"]
    assert cli_main(["compare", "--store", str(store), "--experiment", "pinned",
                     "--save-current", str(tmp_path / "cur.csv")]) in (0, 1)
    out = capsys.readouterr().out
    assert out.count("instruction set:") == 2 and env["isa"] in out


def test_a_config_with_a_bad_pin_is_refused(tmp_path, capsys):
    config = tmp_path / "bad.toml"
    config.write_text(PINNED.replace("pin_isa = true", 'pin_isa = "yes"'))
    assert cli_main(["run", str(config), "--dry-run", "--store", str(tmp_path / "s.sqlite")]) == 2
    assert "experiment.pin_isa: expected true or false" in capsys.readouterr().err
