"""Executing runs: load -> damage -> inpaint -> write frames -> score, each run in its own process.

One run (a `bench.config.RunSpec`) does, inside a worker process (`run_isolated` starts
``python -m bench.runner --worker ...``):

1. load the ground-truth sequence (``bench.datasets.load_dataset`` for names, a PLY folder for paths);
2. damage it with the hole generator and seed of the spec;
3. inpaint with the method, timing each frame; methods whose frames are independent
   (``uses_neighbour_frames = False``) are called frame by frame so that time and memory are per
   frame; a temporal method is called once on the whole sequence and gets sequence-level figures only;
4. write ``damaged/``, ``inpainted/``, ``holes.json`` and ``manifest.json`` into a temporary folder
   and rename it to ``RUNS_DIR/<inpaint_key>`` (atomic: a killed run leaves only a ``.tmp-*`` folder,
   which is never read and is removed by the next runner);
5. score every metric per frame from the frames *as written* (float32 PLY), with
   ``metrics.score_frame`` for scope "frame" (whole frames) and scope "holes" (the frame's regions),
   and ``metrics.temporal_consistency`` at frame -1.

Step 1-4 are skipped when ``RUNS_DIR/<inpaint_key>/manifest.json`` exists (same data, holes and
method): a new metric or peak needs no re-inpainting. The outcome goes back to the driver (as JSON),
which alone writes the results store (`bench.store`), so store writes never race with a worker
being killed.

Per-frame measurements stored as metrics (scope "frame"):
- ``time_s``: wall time of the method on that frame (``time.perf_counter``); at frame -1 the
  method's total time for the sequence.
- ``peak_mem_mb``: peak resident set size of the worker process while the method ran on that frame
  (Linux: ``VmHWM`` from /proc/self/status after resetting it through /proc/self/clear_refs;
  elsewhere ``resource.getrusage(...).ru_maxrss``, the process-lifetime peak). It includes the
  interpreter and loaded libraries, so it is an upper bound of what the method needs; it sees native
  allocations (open3d, pymeshlab) that tracemalloc would miss.
- ``removed_fraction``: share of the frame's points the hole generator removed.
"""

from __future__ import annotations

import importlib
import json
import os
import platform
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import traceback
import uuid
from pathlib import Path

import numpy as np

from bench.config import RunSpec

WORKER_FLAG = "--worker"
_LIVE_PROCESSES: set = set()
_LIVE_LOCK = threading.Lock()


# -- memory and environment --------------------------------------------------------------------
def _reset_peak_rss() -> bool:
    """Reset the kernel's peak-RSS counter of this process (Linux >= 4.0); False when unsupported."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def peak_rss_mb() -> float:
    """Peak resident set size in MiB: VmHWM (since the last reset) on Linux, else ru_maxrss."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0


def git_commit() -> str:
    """The checkout's commit (with "+dirty" when tracked files changed), or "unknown"."""
    repo = Path(__file__).resolve().parents[1]
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True, text=True, timeout=10)
        if commit.returncode != 0:
            return "unknown"
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=repo,
                               capture_output=True, text=True, timeout=10)
        return commit.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def environment() -> dict:
    """Package versions, Python, git commit and machine of this process."""
    from importlib import metadata

    packages = {}
    for name in ("dpcbench", "numpy", "scipy", "open3d", "pymeshlab", "pandas", "matplotlib", "plyfile",
                 "dask", "distributed"):
        try:
            packages[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return {
        "packages": packages,
        "python": platform.python_version(),
        "git_commit": git_commit(),
        "machine": {"node": platform.node(), "system": platform.system(), "release": platform.release(),
                    "arch": platform.machine(), "cpus": os.cpu_count()},
    }


# -- loading ---------------------------------------------------------------------------------
def import_entry(entry: str):
    """The object named by ``"module:Attr"``."""
    module_name, _, attr = entry.partition(":")
    return getattr(importlib.import_module(module_name), attr)


def frame_range(frames, available: int | None = None) -> range | None:
    """The config's ``frames`` (count, or [start, stop)) as a range; None = all."""
    if frames is None:
        return None if available is None else range(available)
    if isinstance(frames, int):
        return range(frames)
    return range(int(frames[0]), int(frames[1]))


def load_ground_truth(sequence: dict):
    """The intact `bench.sequences.Sequence` of a run spec's ``sequence`` entry (frames selected)."""
    from bench.sequences import Sequence, load_sequence

    wanted = frame_range(sequence.get("frames"))
    if sequence.get("path"):
        from bench.meshseq import list_mesh_files

        if list_mesh_files(sequence["path"]) is not None:  # a folder of mesh frames: sampled with its params
            from bench.datasets import load_dataset

            return load_dataset(sequence["path"], frames=None if wanted is None else list(wanted), progress=False,
                                **sequence.get("params", {}))
        seq = load_sequence(sequence["path"], name=sequence.get("label") or sequence["name"])
    else:
        from bench.datasets import load_dataset

        seq = load_dataset(sequence["name"], frames=None if wanted is None else list(wanted),
                           data_dir=sequence.get("data_dir"), progress=False, name_only=True,
                           **sequence.get("params", {}))
        return seq
    if wanted is not None:
        if wanted.stop > len(seq.frames):
            raise ValueError(f"sequence {seq.name!r} has {len(seq.frames)} frames; the config asks for frames "
                             f"{wanted.start}..{wanted.stop - 1}: lower `frames`")
        seq = Sequence(seq.name, [seq.frames[i] for i in wanted], seq.bit_depth,
                       [seq.files[i] for i in wanted] if seq.files else [], seq.meta)
    return seq


# -- producing the frames ----------------------------------------------------------------------
def _inpaint_timed(method, frames: list[np.ndarray], regions) -> tuple[list[np.ndarray], list[dict], dict]:
    """Run the method; per-frame timing for frame-independent methods, one timing otherwise."""
    per_frame: list[dict] = []
    if not getattr(method, "uses_neighbour_frames", False):
        out = []
        for i, frame in enumerate(frames):
            _reset_peak_rss()
            t0 = time.perf_counter()
            result = method.inpaint([frame], None if regions is None else [regions[i]])
            per_frame.append({"frame": i, "time_s": time.perf_counter() - t0, "peak_mem_mb": peak_rss_mb()})
            out.append(result[0])
        total = {"time_s": sum(p["time_s"] for p in per_frame), "peak_mem_mb": max(p["peak_mem_mb"] for p in per_frame)}
        return out, per_frame, total
    _reset_peak_rss()
    t0 = time.perf_counter()
    out = method.inpaint(frames, regions)
    total = {"time_s": time.perf_counter() - t0, "peak_mem_mb": peak_rss_mb()}
    return list(out), per_frame, total


def _check_output(out: list, frames: list, name: str) -> list[np.ndarray]:
    if len(out) != len(frames):
        raise ValueError(f"method {name} returned {len(out)} frames for {len(frames)} input frames")
    checked = []
    for i, arr in enumerate(out):
        arr = np.asarray(arr, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0 or not np.isfinite(arr).all():
            raise ValueError(f"method {name} returned an invalid frame {i} (shape {arr.shape}, must be (N>0, 3) finite)")
        checked.append(arr)
    return checked


def _json_default(value):
    """numpy values inside region extras (e.g. rim points) as plain JSON."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def produce_frames(spec: RunSpec, truth, run_dir: Path) -> None:
    """Damage, inpaint, and write the run folder atomically (temp folder + rename)."""
    from bench.plyio import PointCloud, write_ply
    from holes.regions import regions_to_json

    frames = truth.points
    colors = truth.colors if all(c is not None for c in truth.colors) else None
    if spec.holes["generator"] == "none":  # the data's own holes: nothing removed
        from holes.base import DamageResult

        damage = DamageResult([f.copy() for f in frames], [np.zeros(len(f), bool) for f in frames],
                              [[] for _ in frames], colors)
    else:
        generator = import_entry(spec.holes["entry"])(**spec.holes["params"])
        damage = generator.damage(frames, spec.holes["seed"], colors=colors)
    mode = spec.protocol.get("regions", "given")
    detected, detect_time = None, 0.0
    if mode == "given":
        regions = damage.regions
    elif mode == "detected":
        from holes.detection import detect_holes

        t0 = time.perf_counter()
        detected = [detect_holes(f, **spec.protocol.get("detection", {})) for f in damage.frames]
        detect_time = time.perf_counter() - t0
        regions = detected
    else:
        regions = None
    method = import_entry(spec.method["entry"])(**spec.method["params"])
    inpainted, per_frame, total = _inpaint_timed(method, damage.frames, regions)
    inpainted = _check_output(inpainted, damage.frames, spec.method["name"])

    run_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = run_dir.parent / f".tmp-{run_dir.name}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    tmp.mkdir()
    try:
        for i, (damaged, result) in enumerate(zip(damage.frames, inpainted)):
            dcol = None if damage.colors is None else damage.colors[i]
            write_ply(tmp / "damaged" / f"frame_{i:04d}.ply", PointCloud(damaged, dcol))
            write_ply(tmp / "inpainted" / f"frame_{i:04d}.ply", PointCloud(result))
        holes = regions_to_json(damage.regions, generator=spec.holes["generator"], params=spec.holes["params"],
                                seed=spec.holes["seed"],
                                per_frame=[{"removed_fraction": float(m.mean())} for m in damage.removed])
        (tmp / "holes.json").write_text(json.dumps(holes, indent=1, default=_json_default))
        if detected is not None:
            (tmp / "detected.json").write_text(json.dumps(regions_to_json(detected, detector="holes.detection"), indent=1,
                                                               default=_json_default))
        manifest = {"inpaint_key": spec.inpaint_key, "spec": spec.identity(), "frames": len(frames),
                    "points": [len(f) for f in frames], "per_frame": per_frame, "total": total,
                    "removed_fraction": [float(m.mean()) for m in damage.removed], "regions_mode": mode,
                    "detect_time_s": detect_time, "created_by_pid": os.getpid(),
                    # every parameter as the method resolved it (a variant's switches included)
                    "method_params_resolved": method.get_params()}
        (tmp / "manifest.json").write_text(json.dumps(manifest, indent=1, default=str))
        if run_dir.exists():  # --force, or another worker finished the same frames first: replace
            trash = run_dir.parent / f".tmp-old-{run_dir.name}-{uuid.uuid4().hex[:8]}"
            os.replace(run_dir, trash)
            os.replace(tmp, run_dir)
            shutil.rmtree(trash, ignore_errors=True)
        else:
            os.replace(tmp, run_dir)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def read_run_folder(run_dir: Path) -> dict:
    """The damaged and inpainted frames ((N,3) arrays), regions and manifest of a run folder."""
    from bench.plyio import read_ply
    from bench.sequences import natural_key
    from holes.regions import regions_from_json

    def frames(sub):
        files = sorted((run_dir / sub).glob("*.ply"), key=lambda p: natural_key(p.name))
        return [read_ply(f).points for f in files]

    detected = run_dir / "detected.json"
    return {"damaged": frames("damaged"), "inpainted": frames("inpainted"),
            "regions": regions_from_json(run_dir / "holes.json"),
            "detected": regions_from_json(detected) if detected.is_file() else None,
            "manifest": json.loads((run_dir / "manifest.json").read_text())}


# -- scoring ---------------------------------------------------------------------------------
def _peak_label(peak) -> str:
    if isinstance(peak, str):
        return peak
    return str(int(peak)) if float(peak) == int(peak) else repr(float(peak))


def _uses_peak(name: str) -> bool:
    """Whether the metric's value depends on the PSNR peak (`metrics.registry`, the one source)."""
    from metrics.registry import describe

    metric = describe(name)
    return metric is not None and metric.uses_peak


#: how D2 got the reference normals, as stored in a run's ``env["d2_normals"]`` and printed in captions
D2_NORMALS_FILE = "file"
D2_NORMALS_ESTIMATED = "estimated"
D2_NORMALS_TEXT = {
    D2_NORMALS_FILE: "normals from file (the ground truth's own, as pc_error reads them)",
    D2_NORMALS_ESTIMATED: "normals estimated by PCA of 12 neighbours (the ground truth has none)",
}


def d2_normals_source(truth) -> str:
    """``"file"`` when every ground-truth frame carries normals (the stand-ins' exact normals, or a
    PLY's nx ny nz): D2 uses them, as pc_error does; ``"estimated"`` otherwise (`metrics.pairs.
    estimate_normals` on the frames without)."""
    return D2_NORMALS_FILE if all(f.normals is not None for f in truth.frames) else D2_NORMALS_ESTIMATED


def score_run(spec: RunSpec, truth, inpainted: list[np.ndarray], regions: list) -> list[dict]:
    """Every metric per frame and scope (and peak for PSNRs), plus temporal consistency at frame -1.

    PSNRs are as `metrics.score_pair` returns them (capped at its ``max_psnr``, 200 dB by default,
    when a result equals the reference). D2 uses the ground truth's own normals when its frames carry
    them (`d2_normals_source`), else normals estimated by PCA of 12 neighbours."""
    import metrics as metrics_pkg

    cfg = spec.metrics
    names = cfg["names"]
    peak_names = [n for n in names if _uses_peak(n)]
    rows: list[dict] = []
    for f, (cloud, result) in enumerate(zip(truth.frames, inpainted)):
        # one CloudPair per frame: its KD-trees and neighbour queries serve every scope and peak
        pair = metrics_pkg.make_pair(cloud.points, result, cloud.normals)
        for scope in cfg["scopes"]:
            frame_regions = regions[f] if scope == "holes" else None
            if scope == "holes" and not frame_regions:
                continue  # no hole in this frame: nothing to score in the hole region
            for k, peak in enumerate(cfg["peaks"]):
                wanted = names if k == 0 else peak_names
                if not wanted:
                    continue
                values, _capped = metrics_pkg.score_pair(pair, wanted, peak=peak, regions=frame_regions,
                                                         region_margin=cfg["region_margin"])
                for name, value in values.items():
                    rows.append({"frame": f, "metric": name, "scope": scope,
                                 "peak": _peak_label(peak) if name in peak_names else "", "value": value})
    if cfg.get("temporal_consistency") and len(inpainted) > 1:
        # true point correspondences when the sequence knows them (mesh sequences), else nearest-point links
        motion = getattr(truth, "motion", None)
        value = metrics_pkg.temporal_consistency(truth.points, inpainted, regions, region_margin=cfg["region_margin"],
                                                 correspondences=None if motion is None else motion.correspondences())
        items = value.items() if isinstance(value, dict) else [("temporal_consistency", value)]
        for name, val in items:
            if isinstance(val, (int, float, np.floating)):
                metric = name if name.startswith("temporal_consistency") else f"temporal_consistency_{name}"
                rows.append({"frame": -1, "metric": metric, "scope": "holes", "peak": "", "value": float(val)})
    return rows


def execute_run(spec: RunSpec, runs_dir: str | os.PathLike, *, force: bool = False) -> dict:
    """Do one run in this process; returns the outcome dict the driver stores.

    outcome: {"run_id", "status": "done", "record": {...run facts...}, "results": [rows]}
    Raises on any failure (the worker wrapper turns that into a "failed" outcome).
    """
    t0 = time.perf_counter()
    created = _now()
    run_dir = Path(runs_dir) / spec.inpaint_key
    truth = load_ground_truth(spec.sequence)
    if force or not (run_dir / "manifest.json").is_file():
        produce_frames(spec, truth, run_dir)
        reused = False
    else:
        reused = True
    folder = read_run_folder(run_dir)
    if len(folder["inpainted"]) != len(truth.frames):
        raise ValueError(f"{run_dir}: holds {len(folder['inpainted'])} frames, the sequence has {len(truth.frames)}; "
                         "rerun with --force")
    # without a hole generator there is no ground truth apart from the input itself: no quality scores
    results = [] if spec.holes["generator"] == "none" else score_run(spec, truth, folder["inpainted"], folder["regions"])
    manifest = folder["manifest"]
    for entry in manifest["per_frame"]:
        results.append({"frame": entry["frame"], "metric": "time_s", "scope": "frame", "peak": "", "value": entry["time_s"]})
        results.append({"frame": entry["frame"], "metric": "peak_mem_mb", "scope": "frame", "peak": "",
                        "value": entry["peak_mem_mb"]})
    results.append({"frame": -1, "metric": "time_s", "scope": "frame", "peak": "", "value": manifest["total"]["time_s"]})
    results.append({"frame": -1, "metric": "peak_mem_mb", "scope": "frame", "peak": "",
                    "value": manifest["total"]["peak_mem_mb"]})
    for f, frac in enumerate(manifest["removed_fraction"]):
        results.append({"frame": f, "metric": "removed_fraction", "scope": "frame", "peak": "", "value": frac})
    env = environment()
    env["frames_reused"] = reused
    env["d2_normals"] = d2_normals_source(truth)
    record = {
        "sequence": spec.sequence_label, "holes": spec.holes["generator"], "holes_params": spec.holes["params"],
        "seed": spec.holes["seed"], "method": spec.method["name"], "method_params": spec.method["params"],
        "method_version": spec.versions["method"], "code_version": env["git_commit"], "spec": spec.to_dict(),
        "wall_time_s": time.perf_counter() - t0, "peak_mem_mb": manifest["total"]["peak_mem_mb"], "env": env,
        "created_at": created, "finished_at": _now(), "output_dir": str(run_dir),
    }
    return {"run_id": spec.run_id, "status": "done", "record": record, "results": results}


def _now() -> str:
    from bench.store import now_iso

    return now_iso()


# -- the worker process -------------------------------------------------------------------------
def _exit_with_parent() -> None:
    """End this worker when its driver dies (e.g. kill -9), instead of computing for nobody."""
    parent = os.getppid()

    def watch():
        while True:
            time.sleep(1.0)
            if os.getppid() != parent:
                os._exit(3)

    threading.Thread(target=watch, daemon=True).start()


def worker_main(spec_path: str, out_path: str, runs_dir: str, force: bool) -> int:
    _exit_with_parent()
    spec = RunSpec.from_dict(json.loads(Path(spec_path).read_text()))
    try:
        outcome = execute_run(spec, runs_dir, force=force)
    except BaseException as err:  # every failure becomes a recorded message
        tb = traceback.format_exc()
        outcome = {"run_id": spec.run_id, "status": "failed", "error": f"{type(err).__name__}: {err}",
                   "traceback": tb[-4000:]}
    tmp = Path(out_path + ".tmp")
    tmp.write_text(json.dumps(outcome, default=float))
    os.replace(tmp, out_path)
    return 0


def _tail(path: Path, lines: int = 12) -> str:
    try:
        text = path.read_text(errors="replace").strip().splitlines()
    except OSError:
        return ""
    return "\n".join(text[-lines:])


def run_isolated(spec_dict: dict, runs_dir: str, force: bool = False, threads: int | None = None) -> dict:
    """Run one spec in a fresh ``python -m bench.runner --worker`` process with the spec's timeout.

    Returns the outcome dict; a crash (non-zero exit, a signal such as kill -9, os._exit) or a
    timeout becomes ``{"status": "failed", "error": ...}`` with the exit code and the log's tail.
    Importable by Dask workers (they run it on their machine; ``runs_dir`` must be reachable there).
    """
    spec = RunSpec.from_dict(spec_dict)
    runs = Path(runs_dir)
    logs = runs / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="dpcbench-run-") as tmp:
        spec_path = Path(tmp) / "spec.json"
        out_path = Path(tmp) / "outcome.json"
        spec_path.write_text(json.dumps(spec_dict))
        log_path = logs / f"{spec.run_id}.log"
        env = dict(os.environ, DPCBENCH_QUIET="1", PYTHONUNBUFFERED="1")
        if threads:
            for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
                env.setdefault(var, str(threads))
        cmd = [sys.executable, "-m", "bench.runner", WORKER_FLAG, str(spec_path), str(out_path), str(runs)]
        if force:
            cmd.append("--force")
        t0 = time.perf_counter()
        with open(log_path, "w") as log:
            proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
            with _LIVE_LOCK:
                _LIVE_PROCESSES.add(proc)
            try:
                proc.wait(timeout=spec.timeout_s)
                timed_out = False
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                timed_out = True
            except BaseException:  # Ctrl-C in the driver: the worker goes with it
                proc.kill()
                proc.wait()
                raise
            finally:
                with _LIVE_LOCK:
                    _LIVE_PROCESSES.discard(proc)
        elapsed = time.perf_counter() - t0
        base = {"run_id": spec.run_id, "status": "failed", "wall_time_s": elapsed, "log": str(log_path)}
        if timed_out:
            return {**base, "error": f"timed out after {spec.timeout_s:g} s; the worker was killed "
                                     "(raise experiment.timeout_s or --timeout if the method is just slow)"}
        if out_path.is_file():
            outcome = json.loads(out_path.read_text())
            if outcome["status"] == "failed":
                outcome["log"] = str(log_path)
            return outcome
        code = proc.returncode
        how = f"killed by signal {signal.Signals(-code).name}" if code < 0 else f"exited with code {code}"
        tail = _tail(log_path)
        return {**base, "error": f"worker process {how} without a result" + (f"; last output:\n{tail}" if tail else "")}


def kill_live_workers() -> None:
    """Kill every worker process this driver started (on Ctrl-C)."""
    with _LIVE_LOCK:
        procs = list(_LIVE_PROCESSES)
    for proc in procs:
        try:
            proc.kill()
        except OSError:
            pass


def clean_stale_temp(runs_dir: Path) -> int:
    """Remove ``.tmp-*`` run folders whose writer process is gone (left by killed runs)."""
    removed = 0
    if not runs_dir.is_dir():
        return 0
    for tmp in runs_dir.glob(".tmp-*"):
        parts = tmp.name.split("-")
        pid = None
        if len(parts) >= 4 and parts[1] != "old" and parts[-2].isdigit():
            pid = int(parts[-2])
        alive = False
        if pid is not None:
            try:
                os.kill(pid, 0)
                alive = True
            except (ProcessLookupError, PermissionError):
                alive = False
        if not alive:
            shutil.rmtree(tmp, ignore_errors=True)
            removed += 1
    return removed


# -- the driver ------------------------------------------------------------------------------
class RunSummary:
    """What a sweep did: run ids per outcome ("done" now, "cached" before, "failed" now or before)."""

    def __init__(self):
        self.done: list[str] = []
        self.cached: list[str] = []
        self.failed: list[str] = []
        self.errors: dict[str, str] = {}

    def __repr__(self) -> str:
        return f"RunSummary(done={len(self.done)}, cached={len(self.cached)}, failed={len(self.failed)})"


def default_runs_dir(store_path: Path) -> Path:
    """Run folders live beside the store: ``<store folder>/runs``."""
    return Path(store_path).resolve().parent / "runs"


def _failure_record(spec: RunSpec, outcome: dict) -> dict:
    return {"sequence": spec.sequence_label, "holes": spec.holes["generator"], "holes_params": spec.holes["params"],
            "seed": spec.holes["seed"], "method": spec.method["name"], "method_params": spec.method["params"],
            "method_version": spec.versions["method"], "code_version": git_commit(), "spec": spec.to_dict(),
            "wall_time_s": outcome.get("wall_time_s"), "env": {"log": outcome.get("log"),
                                                              "traceback": outcome.get("traceback")}}


def run_experiment(specs: list[RunSpec], store, *, runs_dir: str | os.PathLike | None = None,
                   executor: str = "pool", jobs: int | None = None, scheduler: str | None = None,
                   force: bool = False, retry_failed: bool = False, quiet: bool = False,
                   timeout_s: float | None = None) -> RunSummary:
    """Execute the runs not yet in ``store`` (a `bench.store.ResultsStore`) and record each as it ends.

    Stored runs are skipped ('done' and 'failed' alike); ``retry_failed`` redoes failed ones,
    ``force`` redoes everything (frames included). Each finished run is written to the store at
    once, in one transaction, so an interrupted sweep keeps all finished runs and loses only those
    in flight, which the next call redoes.
    """
    from bench.executors import make_executor
    from bench.progress import progress_bar

    runs_path = Path(runs_dir).resolve() if runs_dir else default_runs_dir(store.path)
    runs_path.mkdir(parents=True, exist_ok=True)
    clean_stale_temp(runs_path)
    summary = RunSummary()
    statuses = store.statuses([s.run_id for s in specs])
    todo = []
    experiments: dict[str, set[str]] = {}
    for spec in specs:
        experiments.setdefault(spec.experiment, set()).add(spec.run_id)
        status = statuses.get(spec.run_id)
        if force or status is None or (status == "failed" and retry_failed):
            todo.append(spec)
        elif status == "done":
            summary.cached.append(spec.run_id)
        else:
            summary.failed.append(spec.run_id)
            summary.errors[spec.run_id] = "failed in an earlier sweep (use --retry-failed to redo)"
    for name, ids in experiments.items():  # cached runs join this experiment too
        store.add_to_experiment(name, sorted(ids & set(statuses)))
    if timeout_s:
        for spec in todo:
            spec.timeout_s = float(timeout_s)
    if not todo:
        return summary
    runner = make_executor(executor, jobs, scheduler)
    bar = progress_bar(total=len(specs), desc=f"runs ({runner.name} x{runner.jobs})", unit="run", quiet=quiet)
    bar.update(len(summary.cached) + len(summary.failed))

    def show():
        bar.set_postfix_str(f"done {len(summary.done)}, cached {len(summary.cached)}, failed {len(summary.failed)}")

    show()
    try:
        for spec, outcome in runner.execute(todo, runs_path, force):
            if outcome.get("status") == "done":
                store.record_run(spec.run_id, outcome["record"], outcome["results"], [spec.experiment])
                summary.done.append(spec.run_id)
            else:
                error = outcome.get("error", "unknown error")
                store.record_failure(spec.run_id, _failure_record(spec, outcome), error, [spec.experiment])
                summary.failed.append(spec.run_id)
                summary.errors[spec.run_id] = error
                if not quiet:
                    bar.write(f"run {spec.run_id} ({spec.method['name']} on {spec.sequence_label}) failed: "
                              f"{error.splitlines()[0]}")
            bar.update(1)
            show()
    finally:
        bar.close()
    return summary


if __name__ == "__main__":
    if len(sys.argv) >= 5 and sys.argv[1] == WORKER_FLAG:
        sys.exit(worker_main(sys.argv[2], sys.argv[3], sys.argv[4], "--force" in sys.argv[5:]))
    print("usage: python -m bench.runner --worker SPEC_JSON OUTCOME_JSON RUNS_DIR [--force]", file=sys.stderr)
    sys.exit(2)
