"""What several commands share: the input options, where stores, configs and the committed baseline are found.

One module, so that no command imports another (as `dpcbench.bench.cli.commands` modules once did).
"""

from __future__ import annotations

import sys
from contextlib import contextmanager
from pathlib import Path

from dpcbench.bench.core.errors import UserError

#: the source tree (results/ holds the committed baseline and tolerances)
REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_BASELINE = REPO_ROOT / "results" / "regression-baseline.csv"
TOLERANCES_FILE = REPO_ROOT / "results" / "tolerances.toml"
DEFAULT_EXPERIMENT = "regression"
#: the presets `dpcbench run NAME` accepts by name
PRESETS_DIR = Path(__file__).resolve().parents[1] / "presets"


def load_input(source: str, frames=None, data_dir=None, dataset_params=None):
    """The input sequence: an embedded/paper dataset name or a PLY folder/glob/file.

    frames: the text of --frames (a count "10", a list "0,5,9" or a range "0-9"; None: all).
    """
    from dpcbench.bench.data.datasets import load_dataset, parse_frames

    return load_dataset(source, frames=parse_frames(frames), data_dir=data_dir, **(dataset_params or {}))


def add_input_options(parser) -> None:
    """--frames, --data-dir, --dataset-param: of `damage`, `inpaint` and `detect-holes`."""
    parser.add_argument("--frames", default=None,
                        help="frames to use: a count (10), a list (0,5,9) or a range (0-9); default all")
    parser.add_argument("--data-dir", default=None, help="folder holding the paper sequences")
    parser.add_argument("--dataset-param", action="append", metavar="KEY=VALUE",
                        help="parameter of the input (repeatable): an embedded dataset's (--dataset-param size=tiny), "
                             "a mesh sequence's sampling, or voxel_size for PLY frames (re-voxelize coarser: 2 makes "
                             "10-bit frames 9-bit)")


def add_pin_option(parser) -> None:
    """--pin-isa: of `run` and `reproduce-paper`, the commands that start runs."""
    parser.add_argument("--pin-isa", action="store_true",
                        help="run the workers pinned to one instruction set (numpy's AVX2 kernels, OpenBLAS's "
                             "Haswell ones, one BLAS thread: bench/core/isa.py), as an experiment with pin_isa = true "
                             "is: temporal-fusion, temporal-graph and fu-nonlocal then score as on any x86-64 machine "
                             "with AVX2, not only this one. Stored runs are reused whether or not they were pinned "
                             "(the reports say which were): add --force to recompute them")


@contextmanager
def pinned_workers(pin: bool, what: str):
    """The block with `bench.core.isa.pinned` when ``pin`` (saying so on stderr, for ``what``: the experiment), else
    as it is: the runner's workers start inside it, so they inherit the pin before numpy loads; the caller's
    environment comes back after. Yields the variables set ({} unpinned)."""
    if not pin:
        yield {}
        return
    from dpcbench.bench.core import isa

    with isa.pinned() as env:
        print(f"{what}: pinned (pin_isa), workers run with " + " ".join(f"{k}={v!r}" for k, v in sorted(env.items()))
              + " (bench/core/isa.py)", file=sys.stderr)
        yield env


def resolve_store(text: str) -> Path:
    """A results store from a path: the file, or the one store (``results.sqlite`` first) in a folder."""
    path = Path(text).expanduser()
    if path.is_dir():
        candidates = sorted(path.glob("*.sqlite"))
        if (path / "results.sqlite").is_file():
            return path / "results.sqlite"
        if len(candidates) == 1:
            return candidates[0]
        raise UserError(f"{path}: expected one results store (*.sqlite) in the folder, found {len(candidates)}; "
                        "pass the store file itself")
    if not path.is_file():
        raise UserError(f"{path}: no such results store; run `dpcbench run CONFIG --store {path}` first")
    return path


def resolve_config_path(text: str) -> Path:
    """An experiment config from a path, or from a preset name (``paper-quick`` -> bench/presets/paper-quick.toml)."""
    path = Path(text)
    if path.is_file():
        return path
    if path.is_dir():
        raise UserError(f"{text}: is a folder; give an experiment TOML file or a preset name")
    presets = PRESETS_DIR
    stem = path.name.removesuffix(".toml")
    preset = presets / f"{stem}.toml"
    if stem and path.name == text and preset.is_file():  # a bare name, like `paper-quick`
        return preset
    names = ", ".join(sorted(p.stem for p in presets.glob("*.toml")))
    raise UserError(f"{text}: no such config file, and no preset of that name (presets: {names}); "
                    "give the path of an experiment TOML file or one of the preset names")


def run_environment(runs, run_ids) -> dict | None:
    """The environment the runner recorded for these runs (newest run), if it recorded one."""
    import json

    if runs is None or runs.empty or "env" not in runs.columns:
        return None
    chosen = runs[runs["run_id"].isin(run_ids)]
    if chosen.empty:
        return None
    text = chosen.sort_values("created_at")["env"].iloc[-1]
    try:
        env = json.loads(text) if isinstance(text, str) else dict(text or {})
    except (TypeError, ValueError):
        return None
    flat = {}
    for key, value in env.items():  # {"packages": {...}, "machine": ...} -> flat strings
        if isinstance(value, dict):
            flat.update({k: str(v) for k, v in value.items()})
        else:
            flat[key] = str(value)
    return flat


def choose_experiment(store, name: str | None, alternative: str = "") -> str:
    """The experiment of ``store`` a command reads: ``name``, which the store must hold, or with None the store's
    only experiment; UserError otherwise (``alternative``: another way to choose, said in the message)."""
    experiments = store.experiments()
    if name is None:
        if len(experiments) != 1:
            raise UserError(f"the store holds {len(experiments)} experiments ({', '.join(experiments) or 'none'}); "
                            f"choose one with --experiment NAME{alternative}")
        return experiments[0]
    if name not in experiments:
        raise UserError(f"no experiment {name!r} in {store.path}; it holds: {', '.join(experiments) or 'none'}")
    return name
