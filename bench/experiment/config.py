"""Experiment configs (TOML) and their expansion into runs with stable ids.

A config names sequences, hole generators (with parameters and seeds), methods (with parameter
grids), and the metrics with their options::

    [experiment]
    name = "my-sweep"               # required; results are grouped under it in the store
    description = "..."
    timeout_s = 1800                # per run; a run past it is killed and recorded as failed
    regions = "given"               # what methods get: "given" (the generator's hole regions, the
                                    # synthetic-hole protocol), "detected" (holes.detection.detect_holes
                                    # on each damaged frame: the real-hole protocol) or "none" (blind)
    detection = { min_points = 5 }  # with regions = "detected": keyword arguments of detect_holes
    data_dir = "/data/8i"           # where named paper sequences (longdress, ...) are found
    data_role = "heldout"           # optional: "tuning" (data a method's defaults were judged on) or
                                    # "heldout" (data they never saw); recorded in every run's spec
    holds_out = "my-tuning-sweep"   # with data_role = "heldout" (required there): the experiment
                                    # name of the tuning data it is held out from (`dpcbench margins`)
    colour_fill = "auto"            # on coloured data, how new points are coloured (methods._colour.FILLS:
                                    # auto, nearest, harmonic, source); part of a run's identity unless "auto"

    [[sequences]]
    name = "human"                  # an embedded, paper or mesh (samba) dataset name (bench.data.datasets), or ...
    # path = "/data/longdress/Ply"  # ... a folder of PLY frames (or of OBJ/OFF/PLY meshes, sampled
                                    # with params such as points, bit_depth: bench.data.meshseq)
    params = { size = "small" }     # passed to bench.data.datasets.load_dataset; PLY frames (a path, a
                                    # paper sequence) take only voxel_size (re-voxelize on a coarser grid)
    frames = 4                      # the first N frames, or [start, stop) as [0, 8], or every step-th
                                    # frame of [start, stop) as [0, 16, 2] (a lower frame rate)
    label = "Human (stand-in)"      # how reports name it (default: name)
    optional = true                 # data that may be absent (a mesh or paper sequence): skipped, with
                                    # a message, when not found, instead of failing the whole config

    [[holes]]
    generator = "region"            # holes.registry name; "none" = the data's own (real) holes:
                                    # nothing removed, no ground truth, so no quality metrics
    params = { preset = "medium", count = 2 }
    seeds = [0, 1]                  # or seed = 0

    [[methods]]
    name = "temporal-graph"         # methods.registry name
    params = { beta = [0.25, 0.5] } # a list is a grid axis; write [[1, 2]] for a literal list value

    [metrics]
    names = ["gpsnr_d1", "gpsnr_d2", "nshd"]     # default: every registered metric
    peaks = ["intrinsic", 1023]                  # PSNR peaks: "intrinsic" (pc_error default) or numbers
    scopes = ["frame", "holes"]                  # whole frame and/or hole region
    region_margin = 0.0                          # grows the regions for scope "holes"
    temporal_consistency = true

    [labels]                        # optional: names for your paper, used by `dpcbench report --labels`
    "temporal-fusion (ours)" = "Ours"            # method label as the report shows it = name to show
    "temporal-graph (beta=0.25)" = "TG, beta 1/4"

Every list in ``params`` (of sequences, holes and methods) is an axis of a grid; the runs are the
cartesian product sequences x holes (params x seeds) x methods (params). TOML has no null: write "none" for
None where a parameter admits it and takes no text (``params = { bit_depth = "none" }``: a stand-in's float
samples; `metrics.params.none_from_text`).

Run ids. ``inpaint_key = H(sequence spec, data fingerprint, holes spec + seed + generator version,
method spec + method version, protocol [+ detector version])`` names the inpainted frames on disk;
``run_id = H(inpaint_key, metrics spec + metric versions)``. H is the first 16 hex digits of the
SHA-256 of canonical JSON (sorted keys, floats that are whole numbers written as ints, so 1 and 1.0
give the same id). Labels ([labels] too), descriptions and the data role (``data_role``, ``holds_out``) are
presentation only and never change an id. The data
fingerprint is the dataset's name and parameters (embedded data, generated deterministically) or
the name and SHA-256 of every frame file (folders; `bench.data.file_digest` reads a file again only when
its size or modification time changed), so copied, moved or touched data keeps its runs.

Detected regions. With ``regions = "detected"`` what a method gets depends on the detector too, so
those runs' ids also hash every parameter of `holes.detection.detect_holes` as it will be called
(its defaults overlaid with ``experiment.detection``: ``protocol["detection"]``) and the detector's
output version (``versions["detector"]`` = `holes.detection.DETECT_HOLES_VERSION`). A changed
default or a version bump thus gives new ids, and the runner redoes those runs (frames included)
instead of reusing results made from the old detector's regions. With ``regions = "none"`` (blind
mode) each method calls `detect_holes` with its defaults, so those ids carry the detector's version
(not the parameters). Runs with ``regions = "given"`` carry neither.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
import os
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

from dpcbench.bench.core.canonical import canonical_json, stable_hash  # noqa: F401 - re-exported: run ids hash with them
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.core.paper_facts import PAPER_SEQUENCES  # the paper's sequences (name -> row label), one source

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

DEFAULT_TIMEOUT_S = 3600.0
SCOPES = ("frame", "holes")

_TOP_KEYS = {"experiment", "sequences", "holes", "methods", "metrics", "labels"}
_EXPERIMENT_KEYS = {"name", "description", "timeout_s", "regions", "data_dir", "detection", "data_role", "holds_out",
                   "pin_isa", "colour_fill"}
#: values of experiment.data_role: data a method was tuned on, and data it never saw
DATA_ROLES = ("tuning", "heldout")
REGION_MODES = ("given", "detected", "none")
_SEQUENCE_KEYS = {"name", "path", "params", "frames", "label", "optional"}
_HOLES_KEYS = {"generator", "params", "seeds", "seed", "label"}
_METHOD_KEYS = {"name", "params", "label"}
_METRICS_KEYS = {"names", "peaks", "scopes", "region_margin", "temporal_consistency"}


class ConfigError(UserError):
    """A config mistake (a `UserError`); the message starts with the offending key."""


# -- runs ------------------------------------------------------------------------------------
@dataclass
class RunSpec:
    """One run: a sequence damaged by one generator with one seed, inpainted by one configured method.

    sequence: {"name", "path", "params", "frames", "label", "data_dir"}
    holes:    {"generator", "params", "seed", "label", "entry"}  (entry = "module:Class")
    method:   {"name", "params", "label", "entry"}
    metrics:  {"names", "peaks", "scopes", "region_margin", "temporal_consistency"}
    protocol: {"regions": "given" | "detected" | "none", "detection": {...every detect_holes
              parameter, defaults included} (only with "detected")}
    versions: {"method", "generator", "metrics", "data"} (data = fingerprint), plus "detector"
              (`holes.detection.DETECT_HOLES_VERSION`) with regions "detected" or "none"
    """

    run_id: str
    inpaint_key: str
    experiment: str
    sequence: dict
    holes: dict
    method: dict
    metrics: dict
    protocol: dict
    versions: dict
    timeout_s: float = DEFAULT_TIMEOUT_S
    #: the experiment's data role ("tuning" | "heldout" | None) and the tuning experiment a held-out
    #: one holds out from: recorded with the run, never hashed (presentation, like labels)
    data_role: str | None = None
    holds_out: str | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> RunSpec:
        return cls(**data)

    @property
    def sequence_label(self) -> str:
        return self.sequence.get("label") or self.sequence["name"]

    def summary(self) -> str:
        params = ", ".join(f"{k}={v}" for k, v in sorted(self.method["params"].items()))
        hp = ", ".join(f"{k}={v}" for k, v in sorted(self.holes["params"].items()))
        return (f"{self.run_id}  {self.sequence_label}  {self.holes['generator']}({hp}) seed={self.holes['seed']}  "
                f"{self.method['name']}({params})")

    def identity(self) -> dict:
        """What the ids hash (labels excluded)."""
        # where the data lives is not what it is: the fingerprint in `versions` identifies it
        seq = {k: v for k, v in self.sequence.items() if k not in ("label", "data_dir", "path")}
        # "entry" is the import string workers load the class from (so test-registered names work in
        # spawned processes); where the code lives is not what the run computes, so it is not hashed.
        holes = {k: v for k, v in self.holes.items() if k not in ("label", "entry")}
        method = {k: v for k, v in self.method.items() if k not in ("label", "entry")}
        # "detector" only exists for detected-region and blind runs: the ids of the others stay as they were
        versions = {k: self.versions[k] for k in ("method", "generator", "data", "detector") if k in self.versions}
        return {"sequence": seq, "holes": holes, "method": method, "protocol": self.protocol, "versions": versions}


def compute_ids(spec: RunSpec) -> RunSpec:
    spec.inpaint_key = stable_hash(spec.identity())
    spec.run_id = stable_hash({"inpaint": spec.inpaint_key, "metrics": spec.metrics,
                               "metric_versions": spec.versions.get("metrics", {})})
    return spec


# -- validation helpers ----------------------------------------------------------------------
def _is_scalar(v) -> bool:
    """A value a parameter may take: a TOML scalar, or None (a "none" text `_none_from_text` turned into None)."""
    return v is None or isinstance(v, (str, int, float, bool))


def _is_number(v) -> bool:
    """A finite int or float (not a bool; inf and NaN are no config value's meaning)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _expand_params(params: dict, where: str) -> list[dict]:
    """Cartesian product of the list-valued entries; ``[[...]]`` is one literal list value."""
    if not isinstance(params, dict):
        raise ConfigError(f"{where}: expected a table of parameters, got {type(params).__name__}")
    axes = []
    for key, value in params.items():
        if isinstance(value, list):
            if not value:
                raise ConfigError(f"{where}.{key}: an empty list gives no runs; give at least one value")
            for item in value:
                if not (_is_scalar(item) or (isinstance(item, list) and all(_is_scalar(x) for x in item))):
                    raise ConfigError(f"{where}.{key}: grid values must be numbers, strings or booleans, got {item!r}")
            axes.append([(key, v) for v in value])
        elif _is_scalar(value):
            axes.append([(key, value)])
        else:
            raise ConfigError(f"{where}.{key}: expected a value or a list of values, got {type(value).__name__}")
    return [dict(combo) for combo in itertools.product(*axes)] if axes else [{}]


def _check_param_types(cls, params: dict, where: str) -> None:
    """Parameter names must exist in ``cls.__init__`` (or the function ``cls``); a numeric default
    requires numbers."""
    import inspect

    sig = inspect.signature(cls.__init__ if inspect.isclass(cls) else cls)
    known = {n: p for n, p in sig.parameters.items() if n != "self" and p.kind in
             (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)}
    accepts_any = any(p.kind == inspect.Parameter.VAR_KEYWORD for p in sig.parameters.values())
    for key, value in params.items():
        if key not in known:
            if accepts_any:
                continue
            raise ConfigError(f"{where}.{key}: unknown parameter; valid parameters: {', '.join(sorted(known)) or 'none'}")
        default = known[key].default
        # None only comes from a "none" text where the annotation admits it (`_none_from_text`), or from a dict
        # config; either way the class's own check (`_validate_instance`) judges it
        values = [v for v in (value if isinstance(value, list) else [value]) if v is not None]
        if _is_number(default) and not all(_is_number(v) for v in values):
            raise ConfigError(f"{where}.{key}: expected a number or a list of numbers, got {value!r}")
        if isinstance(default, bool) and not all(isinstance(v, bool) for v in values):
            raise ConfigError(f"{where}.{key}: expected true/false or a list of them, got {value!r}")


def _validate_instance(cls, params: dict, where: str) -> None:
    """One grid point through the class's own validation (`validate_params`), so that a bad value
    is refused before any run starts, not when its run fails."""
    from dpcbench.metrics.params import check_param_types

    try:
        # whole numbers where the signature says int
        check_param_types(cls, params, f"{getattr(cls, '_kind', 'class')} {getattr(cls, 'name', '') or cls.__name__}")
        cls(**params).validate_params()
    except UserError as err:
        shown = ", ".join(f"{k}={v!r}" for k, v in params.items())
        raise ConfigError(f"{where}: {err} (in the grid point {shown or 'with no parameters'})") from None


def _check_dataset_name(name, where: str) -> None:
    """A sequence `name` must be an embedded or a paper dataset (a folder goes in `path`)."""
    from dpcbench.bench.data.datasets import EMBEDDED, MESHES, PAPER

    if not isinstance(name, str) or name.lower() not in set(EMBEDDED) | set(PAPER) | set(MESHES):
        import difflib

        known = list(EMBEDDED) + list(PAPER) + list(MESHES)
        close = difflib.get_close_matches(str(name).lower(), known, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ConfigError(f"{where}.name: unknown sequence {name!r}{hint}; known: embedded {', '.join(EMBEDDED)}, "
                          f"paper {', '.join(PAPER)}; for a folder of PLY frames use `path`")


def _none_from_text(func, params, where: str) -> dict:
    """`metrics.params.none_from_text` of a [[...]] table's ``params`` (checked to be a table first)."""
    from dpcbench.metrics.params import none_from_text

    if not isinstance(params, dict):
        raise ConfigError(f"{where}: expected a table of parameters, got {type(params).__name__}")
    return none_from_text(func, params)


def _none_from_text_of_dataset(name: str, params, where: str) -> dict:
    """`_none_from_text` for an embedded dataset's generator; other datasets' parameters as they are."""
    from dpcbench.bench.data.datasets import EMBEDDED

    info = EMBEDDED.get(name.lower())
    return _none_from_text(info.generator().generate_frame, params, where) if info else params


def _check_dataset_params(name: str, params: dict, where: str) -> None:
    """Parameters of an embedded dataset: known names and types (paper sequences take none)."""
    from dpcbench.bench.core.params import check_param_types
    from dpcbench.bench.data.datasets import EMBEDDED, MESHES

    if name.lower() in MESHES:  # mesh sampling parameters are checked by the mesh loader
        return
    info = EMBEDDED.get(name.lower())
    if info is None:  # a paper sequence: PLY frames
        _check_voxel_size(params, where)
        return
    known = info.parameters()
    extra = sorted(set(params) - set(known) - {"cache"})
    if extra:
        raise ConfigError(f"{where}.{extra[0]}: unknown parameter of {name}; valid parameters: {', '.join(known)}")
    try:
        check_param_types(info.generator().generate_frame, {k: v for k, v in params.items() if k != "cache"}, name)
    except UserError as err:
        raise ConfigError(f"{where}: {err}") from None


def _check_voxel_size(params: dict, where: str) -> None:
    """The parameters of PLY frames (a paper sequence, a folder): only ``voxel_size``, an integer >= 1."""
    from dpcbench.bench.data.sources import voxel_size_of

    try:
        voxel_size_of(where, params)
    except UserError as err:
        raise ConfigError(str(err)) from None


def _unknown_keys(table: dict, allowed: set, where: str) -> None:
    extra = sorted(set(table) - allowed)
    if extra:
        raise ConfigError(f"{where}.{extra[0]}: unknown key; allowed keys: {', '.join(sorted(allowed))}")


def _table_list(data: dict, key: str) -> list[dict]:
    items = data.get(key)
    if items is None or items == []:
        raise ConfigError(f"{key}: missing; give at least one [[{key}]] table")
    if isinstance(items, dict):
        items = [items]
    if not isinstance(items, list) or not all(isinstance(t, dict) for t in items):
        raise ConfigError(f"{key}: expected [[{key}]] tables")
    return items


# -- data fingerprints -----------------------------------------------------------------------
def _content_hash(files: list[Path]) -> str:
    """`stable_hash` of each file's name and the SHA-256 of its bytes (`bench.data.file_digest`): the same
    data gives the same runs wherever it lies and whatever its modification times."""
    from dpcbench.bench.data.file_digest import file_digests

    return stable_hash(file_digests(files))


def _mesh_fingerprint(files: list[Path], sequence: dict) -> dict:
    from dpcbench.bench.data.meshseq import GENERATOR_VERSION

    return {"folder": files[0].parent.name, "files": len(files), "content_hash": _content_hash(files),
            "mesh": {"params": sequence.get("params", {}), "version": GENERATOR_VERSION}}


def _folder_fingerprint(folder: Path) -> dict:
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".ply")
    return {"folder": folder.name, "files": len(files), "content_hash": _content_hash(files)}


def data_fingerprint(sequence: dict, where: str) -> dict:
    """What identifies a sequence's data: dataset name + params (+ the datasets module's version if it
    declares one) for generated data; the files' names and content (SHA-256) for folders on disk."""
    if sequence.get("path"):
        path = Path(sequence["path"]).expanduser()
        if not path.exists():
            raise ConfigError(f"{where}.path: {path} does not exist; give a folder of PLY frames")
        from dpcbench.bench.data.meshseq import list_mesh_files

        mesh_files = list_mesh_files(path)
        if mesh_files is not None:
            return _mesh_fingerprint(mesh_files, sequence)
        _check_voxel_size(sequence.get("params", {}), f"{where}.params")
        fingerprint = _folder_fingerprint(path if path.is_dir() else path.parent)
        frames = sequence.get("frames")
        wanted = frames if isinstance(frames, int) else (max(range(*frames)) + 1 if isinstance(frames, list) else 0)
        if fingerprint["files"] == 0:
            raise ConfigError(f"{where}.path: {path} holds no .ply frame; give a folder of PLY frames")
        if wanted > fingerprint["files"]:
            raise ConfigError(f"{where}.frames: asks for {wanted} frames but {path} holds {fingerprint['files']}; "
                              "lower `frames`")
        return fingerprint
    name = sequence["name"]
    from dpcbench.bench.data.datasets import MESHES, find_mesh_folder

    if name.lower() in MESHES:
        info = MESHES[name.lower()]
        folder = find_mesh_folder(info, sequence.get("data_dir"))
        if folder is None:
            raise ConfigError(f"{where}.name: no {info.folder}/{info.pattern.format(0)} found (under experiment.data_dir, "
                              f"--data-dir, $DPCBENCH_DATA_DIR or ../shared/data); {info.title} is published as: "
                              f"{info.source}")
        files = [folder / info.pattern.format(i) for i in range(info.count)]
        return _mesh_fingerprint([p for p in files if p.is_file()], sequence)
    if name.lower() in PAPER_SEQUENCES:
        from dpcbench.bench.data.datasets import PAPER, data_dir_from, find_paper_folder

        root = data_dir_from(sequence.get("data_dir"))
        if root is None:
            raise ConfigError(f"{where}.name: {name!r} is a paper sequence whose data cannot ship with dpcbench; "
                              "set experiment.data_dir (or --data-dir) to the folder holding it, or use `path`")
        folder = find_paper_folder(PAPER[name.lower()], root) if root.is_dir() else None
        if folder is None:
            raise ConfigError(f"{where}.name: no folder of {name} PLY frames under {root}")
        return _folder_fingerprint(folder)
    import dpcbench.bench.data.datasets as datasets

    version = datasets.embedded_version(name.lower())
    return {"dataset": name, "params": sequence.get("params", {}), "version": str(version)}


# -- the config ------------------------------------------------------------------------------
@dataclass
class ExperimentConfig:
    name: str
    description: str = ""
    timeout_s: float = DEFAULT_TIMEOUT_S
    regions: str = "given"
    pin_isa: bool = False
    #: the colour fill of new points on coloured data (`methods._colour.FILLS`)
    colour_fill: str = "auto"
    detection: dict = field(default_factory=dict)
    data_dir: str | None = None
    data_role: str | None = None
    holds_out: str | None = None
    sequences: list[dict] = field(default_factory=list)
    holes: list[dict] = field(default_factory=list)
    methods: list[dict] = field(default_factory=list)
    metrics: dict = field(default_factory=dict)
    #: [labels]: method label -> the name `dpcbench report --labels` shows for it (presentation: not
    #: part of any run, never hashed)
    labels: dict[str, str] = field(default_factory=dict)
    source: str = "<config>"
    #: messages for the optional sequences whose data was not found (filled by `expand`)
    skipped: list[str] = field(default_factory=list)

    def expand(self) -> list[RunSpec]:
        """Every run of the grid, in order sequences x holes x methods; ids computed."""
        return expand_config(self)


def _metric_registry():
    from dpcbench.metrics.registry import METRICS

    return METRICS


def _parse_metrics(table: dict) -> dict:
    if not isinstance(table, dict):
        raise ConfigError("metrics: expected a [metrics] table")
    _unknown_keys(table, _METRICS_KEYS, "metrics")
    registry = _metric_registry()
    names = table.get("names")
    if names is None:
        if registry is None:
            raise ConfigError("metrics.names: the metrics package is unavailable, so no default list; name the metrics")
        # the built-in geometry metrics: an installed metric plug-in does not change a config's runs unless named,
        # and the colour metrics (cpsnr_*) need colours, so they are named
        names = [n for n in registry if n != "temporal_consistency" and n not in registry.plugins
                 and not n.startswith("cpsnr_")]
    if isinstance(names, str):
        names = [names]
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise ConfigError("metrics.names: expected a non-empty list of metric names")
    if registry is not None:
        for i, n in enumerate(names):
            if n not in registry:
                raise ConfigError(f"metrics.names[{i}]: unknown metric {n!r}; known metrics: {', '.join(sorted(registry))}")
            try:
                registry[n]
            except ImportError as err:  # a plug-in metric whose module is missing or broken here
                raise ConfigError(f"metrics.names[{i}]: metric {n!r} cannot be loaded here ({err})") from None
    peaks = table.get("peaks", ["intrinsic"])
    if not isinstance(peaks, list):
        peaks = [peaks]
    for i, p in enumerate(peaks):
        if not (p == "intrinsic" or (_is_number(p) and p > 0)):
            raise ConfigError(f"metrics.peaks[{i}]: expected \"intrinsic\" or a positive number, got {p!r}")
    scopes = table.get("scopes", list(SCOPES))
    if isinstance(scopes, str):
        scopes = [scopes]
    if not isinstance(scopes, list) or not scopes or any(s not in SCOPES for s in scopes):
        raise ConfigError(f"metrics.scopes: expected a list of {list(SCOPES)}, got {scopes!r}")
    margin = table.get("region_margin", 0.0)
    if not _is_number(margin) or margin < 0:
        raise ConfigError(f"metrics.region_margin: expected a non-negative number, got {margin!r}")
    tc = table.get("temporal_consistency", True)
    if not isinstance(tc, bool):
        raise ConfigError("metrics.temporal_consistency: expected true or false")
    return {"names": list(names), "peaks": list(peaks), "scopes": list(scopes), "region_margin": margin,
            "temporal_consistency": tc}


def parse_config(data: dict, source: str = "<config>", base_dir: str | os.PathLike | None = None) -> ExperimentConfig:
    """Validate a config dict (as read from TOML); ConfigError names the offending key."""
    if not isinstance(data, dict):
        raise ConfigError("config: expected a table")
    _unknown_keys(data, _TOP_KEYS, "config")
    cfg = _parse_experiment(data.get("experiment"), source)
    cfg.sequences = _parse_sequences(_table_list(data, "sequences"), base_dir)
    cfg.holes = _parse_holes(_table_list(data, "holes"))
    cfg.methods = _parse_methods(_table_list(data, "methods"))
    cfg.metrics = _parse_metrics(data.get("metrics", {}))
    cfg.labels = parse_labels(data.get("labels", {}))
    return cfg


def parse_labels(table) -> dict[str, str]:
    """The [labels] table: method label as the report shows it (``"temporal-fusion (ours)"``, a
    [[methods]] label, or a name with its distinguishing parameters) -> the name to show instead in
    the tables (Markdown, LaTeX, CSV) and figure legends of `dpcbench report --labels`. Each value is
    a non-empty string, and no two labels get the same name (their columns would merge)."""
    if not isinstance(table, dict):
        raise ConfigError('labels: expected a [labels] table of "method label" = "name in the paper" pairs')
    renamed: dict[str, str] = {}
    for label, name in table.items():
        where = f"labels.{json.dumps(label, ensure_ascii=False)}"
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(f"{where}: expected a non-empty string, the name to show for this method, got {name!r}")
        if name in renamed:
            raise ConfigError(f"{where}: {json.dumps(renamed[name], ensure_ascii=False)} is renamed {name!r} too; "
                              "give each method its own name")
        renamed[name] = label
    return dict(table)


def load_labels(path: str | os.PathLike) -> dict[str, str]:
    """The validated [labels] table of a TOML file (an experiment config; only [labels] is read, so
    that a report can be written where the config's data is not at hand)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such config file")
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise ConfigError(f"{path}: not valid TOML ({err}); fix the syntax at that line") from err
    if "labels" not in data:
        raise ConfigError(f'{path}: no [labels] table; add one with "method label" = "name in the paper" lines')
    try:
        return parse_labels(data["labels"])
    except ConfigError as err:
        raise ConfigError(f"{path}: {err}") from err


def _parse_experiment(exp, source: str) -> ExperimentConfig:
    """The [experiment] table as an `ExperimentConfig` without runs (name, timeout, regions, data role,
    pinning, detection parameters)."""
    if not isinstance(exp, dict) or not exp.get("name"):
        raise ConfigError("experiment.name: missing; add [experiment] with name = \"...\"")
    _unknown_keys(exp, _EXPERIMENT_KEYS, "experiment")
    if not isinstance(exp["name"], str):
        raise ConfigError("experiment.name: expected a string")
    timeout = exp.get("timeout_s", DEFAULT_TIMEOUT_S)
    if not _is_number(timeout) or timeout <= 0:
        raise ConfigError(f"experiment.timeout_s: expected a positive number of seconds, got {timeout!r}")
    regions = exp.get("regions", "given")
    if regions not in REGION_MODES:
        raise ConfigError(f"experiment.regions: expected one of {', '.join(REGION_MODES)}, got {regions!r}")
    role, holds_out = exp.get("data_role"), exp.get("holds_out")
    if role is not None and role not in DATA_ROLES:
        raise ConfigError(f"experiment.data_role: expected one of {', '.join(DATA_ROLES)}, got {role!r}")
    if holds_out is not None and role != "heldout":
        raise ConfigError("experiment.holds_out: only with data_role = \"heldout\"; set data_role or remove it")
    if role == "heldout" and (not isinstance(holds_out, str) or not holds_out or holds_out == exp["name"]):
        raise ConfigError(f"experiment.holds_out: a held-out experiment names the tuning experiment it holds out "
                          f"from (another experiment's name), got {holds_out!r}")
    cfg = ExperimentConfig(name=exp["name"], description=str(exp.get("description", "")), timeout_s=float(timeout),
                           regions=regions, data_dir=exp.get("data_dir"), data_role=role, holds_out=holds_out,
                           source=source)
    if not isinstance(exp.get("pin_isa", False), bool):
        raise ConfigError(f"experiment.pin_isa: expected true or false, got {exp['pin_isa']!r}")
    cfg.pin_isa = exp.get("pin_isa", False)  # run pinned to one instruction set (bench.core.isa), e.g. a regression gate
    from dpcbench.methods._colour import FILLS

    fill = exp.get("colour_fill", "auto")
    if fill not in FILLS:
        raise ConfigError(f"experiment.colour_fill: expected one of {', '.join(FILLS)}, got {fill!r}")
    cfg.colour_fill = fill
    detection = exp.get("detection", {})
    if detection:
        if regions != "detected":
            raise ConfigError("experiment.detection: only used with regions = \"detected\"; remove it or set regions")
        if not isinstance(detection, dict) or not all(_is_scalar(v) for v in detection.values()):
            raise ConfigError("experiment.detection: expected a table of detect_holes parameters (single values)")
        from dpcbench.holes.detection import detect_holes

        _check_param_types(detect_holes, detection, "experiment.detection")
        cfg.detection = dict(detection)
    return cfg


def _check_frames(frames, where: str) -> None:
    """``frames``: None, a positive count, [start, stop) or [start, stop, step]."""
    if frames is None:
        return
    ok = (isinstance(frames, int) and not isinstance(frames, bool) and frames > 0) or (
        isinstance(frames, list) and len(frames) in (2, 3)
        and all(isinstance(x, int) and not isinstance(x, bool) for x in frames)
        and 0 <= frames[0] < frames[1] and (len(frames) == 2 or frames[2] > 0))
    if not ok:
        raise ConfigError(f"{where}.frames: expected a positive count, [start, stop) with start < stop, or "
                          f"[start, stop, step] with step > 0 (every step-th frame), got {frames!r}")


def _parse_sequences(tables: list[dict], base_dir) -> list[dict]:
    """One entry per [[sequences]] table and grid point of its params (with its ``_where`` and ``_optional``)."""
    out = []
    for i, seq in enumerate(tables):
        where = f"sequences[{i}]"
        _unknown_keys(seq, _SEQUENCE_KEYS, where)
        if not seq.get("name") and not seq.get("path"):
            raise ConfigError(f"{where}: give `name` (an embedded or paper dataset) or `path` (a PLY folder)")
        frames = seq.get("frames")
        _check_frames(frames, where)
        path = None
        if seq.get("path"):  # relative paths are relative to the config file's folder
            try:
                path = str((Path(base_dir or ".") / Path(seq["path"]).expanduser()).resolve())
            except (RuntimeError, OSError) as err:  # a symbolic link loop (RuntimeError in Python < 3.13)
                raise ConfigError(f"{where}.path: {seq['path']!r} cannot be resolved ({err}); fix the link") from None
        optional = seq.get("optional", False)
        if not isinstance(optional, bool):
            raise ConfigError(f"{where}.optional: expected true or false, got {optional!r}")
        entry = {"name": seq.get("name") or Path(seq["path"]).name, "path": path,
                 "params": seq.get("params", {}), "frames": frames, "label": seq.get("label")}
        if not path:
            _check_dataset_name(entry["name"], where)
            entry["params"] = _none_from_text_of_dataset(entry["name"], entry["params"], f"{where}.params")
        for params in _expand_params(entry["params"], f"{where}.params"):
            if not path:
                _check_dataset_params(entry["name"], params, f"{where}.params")
            # "_optional" is not part of the run's identity (expand_config drops it)
            out.append({**entry, "params": params, "_where": where, "_optional": optional})
    return out


def _parse_holes(tables: list[dict]) -> list[dict]:
    """One entry per [[holes]] table, grid point of its params and seed (with the generator's entry and version)."""
    from dpcbench.holes.registry import GENERATORS, generator_class

    out = []
    for i, hole in enumerate(tables):
        where = f"holes[{i}]"
        _unknown_keys(hole, _HOLES_KEYS, where)
        gen = hole.get("generator")
        if not isinstance(gen, str) or gen not in GENERATORS:
            raise ConfigError(f"{where}.generator: unknown hole generator {gen!r}; known: {', '.join(sorted(GENERATORS)) or 'none registered'}")
        if "seeds" in hole and "seed" in hole:
            raise ConfigError(f"{where}: give `seeds` or `seed`, not both")
        seeds = hole.get("seeds", [hole.get("seed", 0)])
        if not isinstance(seeds, list) or not seeds or not all(isinstance(s, int) and not isinstance(s, bool)
                                                               and 0 <= s < 2**32 for s in seeds):
            raise ConfigError(f"{where}.seeds: expected a non-empty list of integers in 0..2**32-1, got {seeds!r}")
        try:
            cls = generator_class(gen)
        except ImportError as err:  # an optional dependency or a plug-in's module missing here
            raise ConfigError(f"{where}.generator: hole generator {gen!r} cannot be loaded here ({err})") from None
        if not cls.removes_points:  # the data's own (real) holes: no seed plays a part, one run
            seeds = [0]
        hole_params = _none_from_text(cls, hole.get("params", {}), f"{where}.params")
        _check_param_types(cls, hole_params, f"{where}.params")
        for params in _expand_params(hole_params, f"{where}.params"):
            _validate_instance(cls, params, f"{where}.params")
            for seed in seeds:
                out.append({"generator": gen, "params": params, "seed": seed, "label": hole.get("label"),
                            "entry": GENERATORS[gen], "version": GENERATORS.version_of(gen, cls)})
    return out


def _parse_methods(tables: list[dict]) -> list[dict]:
    """One entry per [[methods]] table and grid point of its params (with the method's entry and version)."""
    from dpcbench.methods.registry import METHODS, method_class

    out = []
    for i, meth in enumerate(tables):
        where = f"methods[{i}]"
        _unknown_keys(meth, _METHOD_KEYS, where)
        name = meth.get("name")
        if not isinstance(name, str) or name not in METHODS:
            raise ConfigError(f"{where}.name: unknown method {name!r}; known methods: {', '.join(sorted(METHODS))}")
        try:
            cls = method_class(name)
        except ImportError as err:  # an optional dependency of this method is missing here
            raise ConfigError(f"{where}.name: method {name!r} cannot be loaded here ({err})") from None
        method_params = _none_from_text(cls, meth.get("params", {}), f"{where}.params")
        _check_param_types(cls, method_params, f"{where}.params")
        for params in _expand_params(method_params, f"{where}.params"):
            _validate_instance(cls, params, f"{where}.params")
            out.append({"name": name, "params": params, "label": meth.get("label"),
                        "entry": METHODS[name], "version": METHODS.version_of(name, cls)})
    return out


def load_config(path: str | os.PathLike, overrides: dict | None = None) -> ExperimentConfig:
    """Read and validate a TOML config; ``overrides`` (a dict) is merged over the file's tables."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such config file")
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise ConfigError(f"{path}: not valid TOML ({err}); fix the syntax at that line") from err
    if overrides:
        data = merge_config(data, overrides)
    try:
        return parse_config(data, source=str(path), base_dir=path.parent)
    except ConfigError as err:
        raise ConfigError(f"{path}: {err}") from err


def merge_config(base: dict, overrides: dict) -> dict:
    """``base`` with ``overrides`` applied: tables merge key by key, everything else is replaced."""
    out = copy.deepcopy(base)
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge_config(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def detection_protocol(detection: dict) -> tuple[dict, str]:
    """(every keyword parameter of `holes.detection.detect_holes` as a run will call it: its
    defaults overlaid with ``detection``, and the detector's output version)."""
    import inspect

    from dpcbench.holes.detection import DETECT_HOLES_VERSION, detect_holes

    defaults = {name: p.default for name, p in inspect.signature(detect_holes).parameters.items()
                if p.kind == inspect.Parameter.KEYWORD_ONLY and p.default is not inspect.Parameter.empty}
    return {**defaults, **detection}, str(DETECT_HOLES_VERSION)


def expand_config(cfg: ExperimentConfig) -> list[RunSpec]:
    """Every run; optional sequences whose data is missing are left out and noted in ``cfg.skipped``
    (also printed to stderr)."""
    cfg.skipped = []
    metric_versions = {}
    registry = _metric_registry()
    if registry is not None:
        for n in cfg.metrics["names"] + (["temporal_consistency"] if cfg.metrics["temporal_consistency"] else []):
            if n in registry:
                metric_versions[n] = str(getattr(registry[n], "version", "1"))
    protocol: dict = {"regions": cfg.regions}
    if cfg.colour_fill != "auto":  # only then: runs of the default fill keep the ids they always had
        protocol["colour_fill"] = cfg.colour_fill
    detector: dict = {}
    if cfg.regions == "detected":
        protocol["detection"], detector["detector"] = detection_protocol(cfg.detection)
    elif cfg.regions == "none":
        # blind mode: each method finds the holes itself with `detect_holes`' defaults, so its output
        # depends on the detector's version as well
        detector["detector"] = detection_protocol({})[1]
    runs: list[RunSpec] = []
    seen: set[str] = set()
    for seq in cfg.sequences:
        sequence = {k: v for k, v in seq.items() if k not in ("_where", "_optional")}
        sequence["data_dir"] = cfg.data_dir
        try:
            fingerprint = data_fingerprint(sequence, seq["_where"])
        except ConfigError as err:
            if not seq.get("_optional"):
                raise
            cfg.skipped.append(f"{seq['_where']} ({sequence.get('label') or sequence['name']}) skipped: {err}")
            continue
        for hole in cfg.holes:
            for meth in cfg.methods:
                spec = RunSpec(
                    run_id="", inpaint_key="", experiment=cfg.name,
                    sequence=copy.deepcopy(sequence),
                    holes={k: copy.deepcopy(v) for k, v in hole.items() if k != "version"},
                    method={k: copy.deepcopy(v) for k, v in meth.items() if k != "version"},
                    metrics=copy.deepcopy(cfg.metrics),
                    protocol=copy.deepcopy(protocol),
                    versions={"method": meth["version"], "generator": hole["version"], "data": fingerprint,
                              "metrics": metric_versions, **detector},
                    timeout_s=cfg.timeout_s, data_role=cfg.data_role, holds_out=cfg.holds_out,
                )
                compute_ids(spec)
                if spec.run_id not in seen:  # the same run listed twice in a grid runs once
                    seen.add(spec.run_id)
                    runs.append(spec)
    for message in cfg.skipped:
        print(f"{cfg.source}: optional {message}", file=sys.stderr)
    return runs
