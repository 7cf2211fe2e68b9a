"""The paper's experiment as `reproduce-paper` runs it: the registry methods behind its columns, the
protocol (presets, sequences, holes) and the subjective figures.

The paper's own facts (sequences, column labels, published Tables 1-2, headline gains) live in
`bench.core.paper_facts`, their one source; they are re-exported here under the same names.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from dpcbench.bench.core.canonical import sorted_json
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.core.paper_facts import (  # noqa: F401  (re-exported: bench.reporting.paper.TABLE1_GPSNR etc. are public)
    CLAIMED_NSHD_FACTOR_OVER_HU,
    CLAIMED_RANKING,
    CLAIMS,
    HEADLINE_GAIN_DB,
    HU_ET_AL,
    PAPER_COLUMNS,
    PAPER_SEQUENCES,
    TABLE1_GPSNR,
    TABLE2_NSHD_E7,
)

if TYPE_CHECKING:
    import pandas as pd

#: The columns of reproduce-paper's Tables 1-2, in order: (registry name, column label, parameters,
#: role). role "paper": the paper's four columns, each run in its paper configuration (MeshLab's
#: whole-frame resampling as the paper describes it; Lozes et al. as `lozes-pde` implements them;
#: Hu et al. and the proposed method with variant="paper"). "ours": our improvements, "reference":
#: reference methods; both are printed beside the paper's columns, never inside them. Adding a
#: column is one line here (reproduce-paper runs exactly these; tests/test_reports.py checks that
#: the paper presets list the same methods for `dpcbench run paper-quick`).
TABLE_COLUMNS: list[tuple[str, str, dict, str]] = [
    ("none", "No fill (floor)", {}, "floor"),
    ("meshlab", "Meshlab", {"output": "whole"}, "paper"),
    ("lozes-pde", "Lozes", {}, "paper"),
    ("fu-nonlocal", "Hu", {"variant": "paper"}, "paper"),
    ("temporal-graph", "Proposed", {"variant": "paper"}, "paper"),
    ("temporal-graph", "temporal-graph tuned (ours)", {}, "ours"),
    ("temporal-fusion", "temporal-fusion (ours)", {}, "ours"),
    ("temporal-copy", "temporal-copy (reference)", {}, "reference"),
]
ROLES = {"floor": "the floor: the damaged input, holes left open (not in the paper)",
         "paper": "the paper's column, in the paper configuration", "ours": "ours (not in the paper)",
         "reference": "reference (not in the paper)"}

#: (registry name, column label in the paper, parameters) of the paper's four columns, in its order
PAPER_METHODS: list[tuple[str, str, dict]] = [(n, label, p) for n, label, p, role in TABLE_COLUMNS if role == "paper"]
if tuple(label for _, label, _ in PAPER_METHODS) != PAPER_COLUMNS:
    raise AssertionError("dpcbench.bench.reporting.paper.TABLE_COLUMNS: the 'paper' columns must be bench.core.paper_facts.PAPER_COLUMNS, "
                         "in order")
#: the paper's column labels (its Tables 1-2) and every column of ours (paper's first)
COLUMNS = list(PAPER_COLUMNS)
ALL_COLUMNS = [label for _, label, _, _ in TABLE_COLUMNS]


def _params_key(params) -> str:
    """Canonical JSON of a parameter dict (or of its JSON text), as the results store keeps it."""
    import json

    value = json.loads(params) if isinstance(params, str) and params else (params or {})
    return sorted_json(value)


#: (registry name, canonical parameters JSON) -> column label
COLUMN_OF = {(name, _params_key(params)): label for name, label, params, _ in TABLE_COLUMNS}


def column_label(method: str, params) -> str:
    """The table column of a method configuration: its label in `TABLE_COLUMNS`, else the registry
    name with its parameters (a configuration that is not a column never joins one)."""
    key = _params_key(params)
    return COLUMN_OF.get((method, key), method if key == "{}" else f"{method} {key}")


def table_methods() -> list[dict]:
    """`TABLE_COLUMNS` as experiment-config [[methods]] tables."""
    return [{"name": name, "params": dict(params), "label": label} for name, label, params, _ in TABLE_COLUMNS]


def paper_column(df: pd.DataFrame) -> pd.Series:
    """The table column of each row: `bench.reporting.paper.column_label` of its method and parameters (so the
    paper configuration of temporal-graph is "Proposed" and our tuned one its own column)."""
    import pandas as pd

    params = df["method_params"] if "method_params" in df else pd.Series("{}", index=df.index)
    return pd.Series([column_label(m, p) for m, p in zip(df["method"], params)], index=df.index, dtype=object)


def column_descriptions(with_all_params: bool = False) -> list[dict]:
    """Per column: label, role, registry method, the parameters given, the method's version and,
    with ``with_all_params``, every parameter as the method resolves it (`get_params`, switches of
    a variant included) at this code version."""
    from dpcbench.methods.registry import method_class

    out = []
    for name, label, params, role in TABLE_COLUMNS:
        entry = {"label": label, "role": role, "method": name, "params": dict(params)}
        try:
            cls = method_class(name)
            entry["version"] = str(getattr(cls, "version", "1"))
            if with_all_params:
                entry["all_params"] = cls(**params).get_params()
        except ImportError as err:  # an optional dependency missing here: say so, keep the rest
            entry["version"] = f"unavailable ({err})"
        out.append(entry)
    return out


def columns_caption() -> str:
    """One sentence naming, for each column, the registry method and its exact parameters."""
    parts = []
    for d in column_descriptions(with_all_params=True):
        given = ", ".join(f"{k}={v}" for k, v in sorted(d["params"].items())) or "defaults"
        variant = d.get("all_params", {}).get("variant")
        if variant and "variant" not in d["params"]:
            given += f": variant={variant}"
        parts.append(f"{d['label']} = `{d['method']}` ({given}; version {d['version']})")
    return ("Columns: " + "; ".join(parts) + f". Meshlab, Lozes, Hu and Proposed are the paper's columns "
            f"(Hu: {HU_ET_AL}): Hu and "
            "Proposed in the paper configuration (variant=paper: every step as the paper writes it, every addition "
            "of ours off), MeshLab resampling the whole frame as the paper describes, Lozes as lozes-pde implements "
            "Lozes et al.; '(ours)' and '(reference)' columns are not in the paper, nor is the floor (no fill: the damaged "
            "input unchanged). Every parameter value: "
            "REPORT.md, 'Columns'.")


#: embedded stand-ins used when the paper's data is not given -> row label (always says stand-in)
STANDINS = {"human": "Human (stand-in)", "bunny": "Bunny (stand-in)"}

#: real captured motion added as extra rows when its data is found -> row label: a registered mesh sequence
#: (bench.data.datasets.MESHES, sampled at `REAL_MOTION_POINTS`) or a key of `REAL_MOTION_FOLDERS`
REAL_MOTION = {"dfaust": "D-FAUST punching (real captured motion, not one of the paper's sequences)",
               "samba": "Samba (real captured motion, not one of the paper's sequences)"}
#: the mesh sequences' points per frame by stand-in size (None: fill the 10-bit grid, ~790k points, like an 8i capture)
REAL_MOTION_POINTS = {"tiny": 20_000, "small": 100_000, "default": None}
#: real captured motion stored as a folder of PLY point clouds (read as captured, whatever the size: D-FAUST
#: punching is 17 frames of 100k unvoxelized points), looked up by folder name under the data folder
REAL_MOTION_FOLDERS = {"dfaust": "dfaust_50004_punching"}


def real_motion_rows(data_dir, frames, points: int | None) -> list[dict]:
    """The experiment's ``[[sequences]]`` entries of `REAL_MOTION`, each optional (skipped with a message
    when its data is missing): a mesh sequence by name with ``points`` a frame, a point-cloud folder by
    path, found under ``data_dir`` (else $DPCBENCH_DATA_DIR, else `default_data_dirs`, as the mesh
    sequences are); a folder found nowhere is listed at its first candidate path, so the skip names it."""
    from dpcbench.bench.data.sources import (
        data_dir_from,
        meshes,  # its default_data_dirs, looked up at call time
    )

    rows = []
    roots = [r for r in [data_dir_from(data_dir)] if r is not None] + meshes.default_data_dirs()
    for name, label in REAL_MOTION.items():
        entry: dict = {"frames": frames, "label": label, "optional": True}
        folder = REAL_MOTION_FOLDERS.get(name)
        if folder is None:
            rows.append({"name": name, **entry, "params": {} if points is None else {"points": points}})
            continue
        found = [root / folder for root in roots if (root / folder).is_dir()]
        if found or roots:
            rows.append({"path": str((found or [roots[0] / folder])[0]), **entry})
    return rows


def paper_table(metric: str) -> dict[str, dict[str, float]]:
    """row label -> {column label: paper value} for "gpsnr" (dB) or "nshd" (x1e-7)."""
    source = TABLE1_GPSNR if metric.startswith("gpsnr") else TABLE2_NSHD_E7
    return {row: dict(zip(COLUMNS, values)) for row, values in source.items()}


def paper_mean_gains() -> dict[str, float]:
    """Average over the five sequences of Proposed minus each method, from Table 1 (dB).

    Recomputed from the table: Meshlab 26.80, Lozes 16.18, Hu 5.26 (the paper's text)."""
    rows = list(TABLE1_GPSNR.values())
    proposed = [r[3] for r in rows]
    return {col: sum(p - r[i] for p, r in zip(proposed, rows)) / len(rows) for i, col in enumerate(COLUMNS[:3])}


# -- the protocol `reproduce-paper` runs ----------------------------------------------------------
PRESETS_DIR = __import__("pathlib").Path(__file__).resolve().parents[1] / "presets"
#: consecutive frames shown in the subjective figures and used for the real-hole runs
REAL_HOLE_FRAMES = 3
#: detect_holes parameters for the stand-in's acquisition holes. Measured on the quick preset (tiny
#: human, occlusion generator version 1 (HPR), 3 frames with 3-7 true holes of radius 2-4 voxels): the
#: defaults found no hole in any frame; these found one per frame, each centred within 0.4 voxels of a
#: true hole. With `STANDIN_OCCLUSION` (version 2) they find 3-4 regions a frame holding 66-77 % of the
#: removed points (233-263 of ~23.8k points removed a frame, in 12-14 pieces).
STANDIN_DETECTION = {"gap": 1.5707963267948966, "min_points": 5, "min_inward": 0.0}
#: occlusion rig for the stand-in's acquisition holes: one ring of 3 cameras at mid-height (a low-cost
#: rig). The default stage (2 rings of 6) sees all but 2-3 points a frame of the tiny human (186 voxels
#: tall) with the z-buffer, and detect_holes finds nothing there; this rig leaves holes at the sides of
#: the chest and under the arms (measured, tiny human frames 0-2).
STANDIN_OCCLUSION = {"rings": [[0.5]], "per_ring": 3}  # [[...]]: one literal list (config grids)


class PaperProtocol:
    """The runs of `reproduce-paper`: ``synthetic`` (Tables 1-2, Fig. 4) and ``real`` (Fig. 3).

    standins: True when the sequences are the embedded stand-ins (no --data-dir).
    """

    def __init__(self, preset: str, standins: bool, synthetic: list, real: list, config: dict):
        self.preset = preset
        self.standins = standins
        self.synthetic = synthetic
        self.real = real
        self.config = config


def available_paper_sequences(data_dir) -> list[str]:
    """Names (bench.data.datasets.PAPER keys) of the paper's sequences found under ``data_dir``."""
    from pathlib import Path

    from dpcbench.bench.data.datasets import PAPER, find_paper_folder

    root = Path(data_dir).expanduser()
    if not root.is_dir():
        raise UserError(f"--data-dir {root}: no such folder; give the folder that holds e.g. longdress/Ply/*.ply")
    return [name for name in PAPER_SEQUENCES if find_paper_folder(PAPER[name], root) is not None]


def paper_protocol(quick: bool, data_dir=None, *, size: str | None = None, frames: int | None = None,
                   seeds: list[int] | None = None) -> PaperProtocol:
    """Expand the preset (paper-quick.toml or paper.toml) into runs: the methods of `TABLE_COLUMNS`,
    the preset's sequences and holes (``seeds`` replaces the synthetic holes' seeds).

    Synthetic holes: the preset's sequences (stand-ins) or, with ``data_dir``, every paper sequence
    found there with the preset's frame count. Real holes (Fig. 3): on the stand-in human, acquisition
    holes from the "occlusion" generator, regions *detected* by `holes.detection.detect_holes` (the
    ground truth is known, so they are scored too); on the paper's data, the first sequence's own
    capture holes (no hole generator, no ground truth, not scored), regions detected likewise.
    """
    import copy

    from dpcbench.bench.experiment.config import (
        parse_config,  # stdlib tomllib, or tomli on Python 3.10
        tomllib,  # stdlib tomllib, or tomli on Python 3.10
    )

    preset = "paper-quick" if quick else "paper"
    base = tomllib.loads((PRESETS_DIR / f"{preset}.toml").read_text())
    base["methods"] = table_methods()  # the table's columns, whatever the preset lists
    if seeds is not None:
        if not seeds or any(not isinstance(x, int) or isinstance(x, bool) or x < 0 for x in seeds):
            raise UserError(f"--seeds: give non-negative integers, e.g. --seeds 0,1,2 (got {seeds!r})")
        for hole in base["holes"]:
            hole["seeds"] = list(seeds)
    if frames is not None and frames < 2:
        raise UserError("--frames: the temporal method needs at least 2 frames")
    for seq in base["sequences"]:
        if size:
            seq.setdefault("params", {})["size"] = size
        if frames:
            seq["frames"] = frames
    frames = base["sequences"][0].get("frames")
    standins = True
    synthetic_cfg = copy.deepcopy(base)
    real_cfg = copy.deepcopy(base)
    real_cfg["experiment"]["name"] = f"{preset}-real-holes"
    real_cfg["experiment"]["regions"] = "detected"
    if data_dir:
        from dpcbench.bench.data.datasets import PAPER
        from dpcbench.bench.data.sources.paper import single_frame_rows

        # a sequence found as one real frame (`8i_longdress_1300/longdress_vox10_1300.ply`, or
        # `longdress/Ply/` holding one file) is a row of its own, read by path, with the per-frame columns
        singles = single_frame_rows(PAPER, data_dir, PAPER_SEQUENCES)
        found = [n for n in available_paper_sequences(data_dir) if n not in singles]
        if not found and not singles:
            raise UserError(f"--data-dir {data_dir}: none of the paper's sequences ({', '.join(PAPER_SEQUENCES)}) "
                             "found there; expected e.g. longdress/Ply/longdress_vox10_1051.ply ... (see "
                             "`dpcbench list --data-dir DIR`), or leave --data-dir out to run on the embedded stand-ins")
        standins = False
        synthetic_cfg["experiment"]["name"] = f"{preset}-data"
        synthetic_cfg["experiment"]["data_dir"] = str(data_dir)
        synthetic_cfg["sequences"] = ([{"name": n, "frames": frames, "label": PAPER_SEQUENCES[n]} for n in found]
                                      + list(singles.values()))
        real_cfg["experiment"]["name"] = f"{preset}-data-real-holes"
        real_cfg["experiment"]["data_dir"] = str(data_dir)
        real_cfg["sequences"] = ([{"name": found[0], "frames": REAL_HOLE_FRAMES, "label": PAPER_SEQUENCES[found[0]]}]
                                 if found else [next(iter(singles.values()))])
        real_cfg["holes"] = [{"generator": "none"}]
    else:
        first = copy.deepcopy(base["sequences"][0])
        first["frames"] = [0, REAL_HOLE_FRAMES]
        real_cfg["sequences"] = [first]
        real_cfg["holes"] = [{"generator": "occlusion", "params": dict(STANDIN_OCCLUSION), "seed": 0}]
        real_cfg["experiment"]["detection"] = dict(STANDIN_DETECTION)
    # real captured motion (D-FAUST punching, read as captured; samba, a mesh sequence with exact
    # correspondences), when its data is found; optional sequences, so each is skipped with a message otherwise
    points = REAL_MOTION_POINTS[size or ("tiny" if quick else "default")]
    synthetic_cfg["sequences"] += real_motion_rows(data_dir, frames, points)
    synthetic = parse_config(synthetic_cfg, source=f"preset {preset}").expand()
    real = parse_config(real_cfg, source=f"preset {preset} (real holes)").expand()
    return PaperProtocol(preset, standins, synthetic, real, synthetic_cfg)


def _done_folders(store, specs) -> dict:
    """column label (`column_label`) -> (spec, run folder) of the done runs among ``specs`` (first
    per column: temporal-graph's paper configuration and ours are different columns)."""
    from pathlib import Path

    runs = store.runs_frame().drop_duplicates("run_id").set_index("run_id")
    out = {}
    for spec in specs:
        column = column_label(spec.method["name"], spec.method["params"])
        if spec.run_id in runs.index and runs.loc[spec.run_id, "status"] == "done" and column not in out:
            out[column] = (spec, Path(runs.loc[spec.run_id, "output_dir"]))
    return out


#: frames shown in the subjective figures: each adds a row of bodies and a zoom row per hole, and the
#: figure is printed a page wide (two frames of a few holes fill about a page's height)
FIGURE_FRAMES = 2
#: a frame after the first is shown only while the zoom rows stay within this many (a row is about
#: 0.75 in at 7.2 in wide: 8 rows and two rows of bodies are about a page)
MAX_ZOOM_ROWS = 8


def shown_frames(candidates: list[int], hole_counts: list[int]) -> list[int]:
    """The frames of a subjective figure: the first of ``candidates``, then the next ones while the
    holes of the frames shown (``hole_counts``, per candidate) stay within `MAX_ZOOM_ROWS`."""
    shown: list[int] = []
    rows = 0
    for frame, count in zip(candidates, hole_counts):
        if shown and rows + count > MAX_ZOOM_ROWS:
            break
        shown.append(frame)
        rows += count
    return shown


def figure_columns(done: dict, frames_of) -> tuple[list[tuple[str, list]], list, list[str]]:
    """The method columns of a subjective figure: every non-floor column of `TABLE_COLUMNS` (the
    paper's, ours, the references) whose run is in ``done`` (column label -> (spec, folder)), in
    that order (the floor is the damaged input, already a column); ``frames_of(folder)`` gives a
    run's shown frames. Returns (columns, their palette colours, the labels missing from ``done``)."""
    from dpcbench.bench.reporting import palette

    colours = palette.configuration_colours((label, name) for name, label, _, _ in TABLE_COLUMNS)
    columns, column_colours, missing = [], [], []
    for _, label, _, role in TABLE_COLUMNS:
        if role == "floor":
            continue
        if label not in done:
            missing.append(label)
            continue
        columns.append((label, frames_of(done[label][1])))
        column_colours.append(colours[label])
    return columns, column_colours, missing


def _figure4(protocol: PaperProtocol, store, fig_dir) -> dict[str, str]:
    """Fig. 4-like: the first synthetic sequence with its first temporally coherent hole
    configuration when there is one (its holes follow the surface through the frames shown), else
    the first; the first and last frames; every hole of each magnified."""
    import numpy as np

    from dpcbench.bench.data.datasets import load_run_sequence
    from dpcbench.bench.execution.provenance import read_run_folder
    from dpcbench.bench.reporting.figures import subjective_grid

    first_seq = protocol.synthetic[0].sequence_label if protocol.synthetic else None
    on_first = [s.holes for s in protocol.synthetic if s.sequence_label == first_seq]
    first_holes = next((h for h in on_first if h["params"].get("coherent")), on_first[0] if on_first else None)
    specs = [s for s in protocol.synthetic if s.sequence_label == first_seq and s.holes == first_holes]
    done = _done_folders(store, specs)
    if not done:
        return {}
    assert first_holes is not None  # done's specs are runs with first_holes
    spec0, folder0 = next(iter(done.values()))
    truth = load_run_sequence(spec0.sequence)
    content0 = read_run_folder(folder0)
    n = len(truth.frames)
    regions = content0["regions"]
    candidates = sorted(set(np.linspace(0, n - 1, min(FIGURE_FRAMES, n)).round().astype(int).tolist()))
    shown = shown_frames(candidates, [len(regions[f]) for f in candidates])
    methods, colours, missing = figure_columns(done, lambda folder: [read_run_folder(folder)["inpainted"][f]
                                                                     for f in shown])
    columns = [("Ground truth", [truth.frames[f].points for f in shown]),
               ("With holes", [content0["damaged"][f] for f in shown])] + methods
    holes = first_holes.get("label") or first_holes["generator"]
    subjective_grid(columns, [f"f={f}" for f in shown], Path(fig_dir) / "fig4_synthetic_holes.png",
                    hole_regions=[regions[f] for f in shown], column_colours=[None, None] + colours,
                    title=f"Synthetic holes ({holes}), {first_seq}")
    counts = [len(regions[f]) for f in shown]
    return {"fig4_synthetic_holes": (
        f"Like the paper's Fig. 4: {first_seq}, {holes}, seed {first_holes['seed']}; columns ground truth, with holes, "
        "then every column of the tables that ran (the paper's four in the paper configuration, ours, the "
        f"reference), titled in the methods' colours; rows frames {shown}, each followed by one magnified row "
        f"per hole of that frame ({counts} holes), the hole's orange square numbered on the bodies; points "
        "inside the hole regions are tinted red in the method columns (the key under the figure)."
        + (f" Missing (run failed): {', '.join(missing)}." if missing else ""))}


def _figure3(protocol: PaperProtocol, store, fig_dir) -> dict[str, str]:
    """Fig. 3-like: detected holes on the first consecutive frames, every detection magnified."""
    from dpcbench.bench.data.datasets import load_run_sequence
    from dpcbench.bench.execution.provenance import read_run_folder
    from dpcbench.bench.reporting.figures import subjective_grid

    done = _done_folders(store, protocol.real)
    if not done:
        return {}
    spec0, folder0 = next(iter(done.values()))
    truth = load_run_sequence(spec0.sequence)
    content0 = read_run_folder(folder0)
    detected = content0["detected"] or [[] for _ in content0["damaged"]]
    candidates = list(range(min(FIGURE_FRAMES, len(content0["damaged"]))))
    shown = shown_frames(candidates, [len(detected[f]) for f in candidates])
    if protocol.standins:
        columns = [("Ground truth", [truth.frames[f].points for f in shown]),
                   ("Acquisition holes", [content0["damaged"][f] for f in shown])]
    else:
        columns = [("Captured", [content0["damaged"][f] for f in shown]),
                   ("Captured (detected holes)", [content0["damaged"][f] for f in shown])]
    methods, colours, missing = figure_columns(done, lambda folder: [read_run_folder(folder)["inpainted"][f]
                                                                     for f in shown])
    subjective_grid(columns + methods, [f"f={f}" for f in shown], Path(fig_dir) / "fig3_real_holes.png",
                    hole_regions=[detected[f] for f in shown], column_colours=[None, None] + colours,
                    title=f"Detected holes, {spec0.sequence_label}")
    counts = [len(d) for d in detected]
    source = ("acquisition holes simulated by the occlusion generator (a capture rig's blind spots), whose "
              "ground truth is known: these runs are scored too (table 'real_holes_gpsnr')"
              if protocol.standins else "the sequence's own capture holes (no ground truth: not scored)")
    return {"fig3_real_holes": (
        f"Like the paper's Fig. 3: {source}. The methods get the regions found by "
        f"`holes.detection.detect_holes` ({counts} regions per frame), not the true ones; columns as in Fig. 4 "
        f"(every column of the tables that ran); rows the consecutive frames {shown}, each followed by one "
        "magnified row per detected hole (its orange square numbered on the bodies); points inside the "
        "detected regions are tinted red in the method columns."
        + (f" Missing (run failed): {', '.join(missing)}." if missing else "")
        + (" No hole was detected in these frames, so every method returned them unchanged: the "
           "detector's parameters (holes.detection) decide what this figure can show." if not any(counts) else ""))}


def paper_figures(protocol: PaperProtocol, store, fig_dir) -> dict[str, str]:
    """Fig. 4-like (synthetic holes) and Fig. 3-like (detected real holes) subjective figures
    (`_figure4`, `_figure3`), PNG and PDF.

    Returns figure stem -> a caption for REPORT.md. A figure whose runs did not finish is skipped."""
    return {**_figure4(protocol, store, fig_dir), **_figure3(protocol, store, fig_dir)}
