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
    assert "pinned (pin_isa), workers run with" in capsys.readouterr().err
    assert not any(var in os.environ for var in isa.PIN_VARIABLES)  # the caller's environment is given back
    env = json.loads(ResultsStore(store, readonly=True).runs_frame()["env"].iloc[0])
    expected = isa.pin_environment()
    if "NPY_DISABLE_CPU_FEATURES" in expected:
        assert "numpy dispatch up to X86_V3; pinned" in env["isa"]
    assert cli_main(["compare", "--store", str(store), "--experiment", "pinned",
                     "--save-current", str(tmp_path / "cur.csv")]) in (0, 1)
    out = capsys.readouterr().out
    assert out.count("instruction set:") == 2 and env["isa"] in out


@pytest.mark.parametrize("command", [["run", "CONFIG"], ["reproduce-paper", "--quick"]])
def test_pin_isa_pins_the_workers_of_an_unpinned_experiment_and_gives_the_environment_back(command, tmp_path,
                                                                                            monkeypatch, capsys):
    """`--pin-isa` on `run` (an experiment without pin_isa) and on `reproduce-paper`: the runner is called with the
    pin in os.environ (its workers inherit it), and without the flag it is not; the caller's environment comes back."""
    from dpcbench.bench.execution import runner

    for var in isa.PIN_VARIABLES:
        monkeypatch.delenv(var, raising=False)
    seen = []

    def runner_seeing_the_environment(specs, store, **kwargs):
        seen.append({var: os.environ.get(var) for var in isa.PIN_VARIABLES})
        return runner.RunSummary()  # nothing run: each command then stops with its own message

    monkeypatch.setattr(runner, "run_experiment", runner_seeing_the_environment)
    config = tmp_path / "unpinned.toml"
    config.write_text(PINNED.replace("pin_isa = true\n", ""))
    args = [str(config) if a == "CONFIG" else a for a in command] + ["--store", str(tmp_path / "s.sqlite"), "--quiet"]
    if command[0] == "reproduce-paper":
        args += ["--out", str(tmp_path / "out")]
    cli_main(args)
    cli_main(args + ["--pin-isa"])
    assert "pinned (pin_isa), workers run with" in capsys.readouterr().err
    assert seen[0] == dict.fromkeys(isa.PIN_VARIABLES)
    assert seen[1] == {var: isa.pin_environment().get(var) for var in isa.PIN_VARIABLES}
    assert not any(var in os.environ for var in isa.PIN_VARIABLES)


def test_a_config_with_a_bad_pin_is_refused(tmp_path, capsys):
    config = tmp_path / "bad.toml"
    config.write_text(PINNED.replace("pin_isa = true", 'pin_isa = "yes"'))
    assert cli_main(["run", str(config), "--dry-run", "--store", str(tmp_path / "s.sqlite")]) == 2
    assert "experiment.pin_isa: expected true or false" in capsys.readouterr().err
