"""The worker: one run (load -> damage -> inpaint -> write frames -> score) in its own process.

The sweep driver (`bench.execution.runner.run_experiment`) hands runs to an executor (`bench.execution.executors`), which
calls `run_isolated` for each; that starts ``python -m dpcbench.bench.execution.worker --worker ...``, and the worker
process does, for one run (a `bench.experiment.config.RunSpec`):

1. load the ground-truth sequence (`bench.data.datasets.load_run_sequence`: a dataset name or a path);
2. damage it with the hole generator and seed of the spec;
3. inpaint with the method, timing each frame; methods whose frames are independent
   (``uses_neighbour_frames = False``) are called frame by frame so that time and memory are per
   frame; a temporal method is called once on the whole sequence and gets sequence-level figures only;
4. write the run folder ``RUNS_DIR/<inpaint_key>`` (`bench.execution.provenance.write_run_folder`: atomic, a
   killed run leaves only a ``.tmp-*`` folder, which is never read and is removed by the next sweep);
5. score every metric per frame from the frames *as written* (float32 PLY), with
   ``metrics.score_frame`` for scope "frame" (whole frames) and scope "holes" (the frame's regions),
   and ``metrics.temporal_consistency`` at frame -1.

Step 1-4 are skipped when ``RUNS_DIR/<inpaint_key>/manifest.json`` exists (same data, holes and
method): a new metric or peak needs no re-inpainting. The outcome goes back to the driver (as JSON),
which alone writes the results store (`bench.results.store`), so store writes never race with a worker
being killed.

Per-frame measurements stored as metrics (scope "frame"):
- ``time_s``: wall time of the method on that frame (``time.perf_counter``); at frame -1 the
  method's total time for the sequence.
- ``cpu_time_s``: CPU time (user + system) the method took on that frame: the change of
  `process_cpu_s` across the call, i.e. every thread of the worker process (BLAS, OpenMP, open3d)
  plus its waited-for child processes; at frame -1 the total. On a shared machine the wall time
  grows with the load while the CPU time barely does; CPU > wall means the method used several
  cores. Absent for run folders written before it was measured (reused frames keep their figures).
- ``peak_mem_mb``: peak resident set size of the worker process while the method ran on that frame
  (Linux: ``VmHWM`` from /proc/self/status after resetting it through /proc/self/clear_refs;
  elsewhere ``resource.getrusage(...).ru_maxrss``, the process-lifetime peak). It includes the
  interpreter and loaded libraries, so it is an upper bound of what the method needs; it sees native
  allocations (open3d, pymeshlab) that tracemalloc would miss. Generated sequences are in the frame cache
  before the runs start (`bench.execution.runner.warm_caches`), so loading one never imports what generating it
  needs into the worker.
- ``removed_fraction``: share of the frame's points the hole generator removed.

Per run (columns of the store's ``runs`` table): ``wall_time_s`` and ``cpu_time_s`` over the same span,
from the start of `execute_run` (after the worker's interpreter started and imported this module)
to its end: loading, damage, inpainting, writing and scoring. A run that crashes or times out is
timed by the driver instead, over the whole worker process (`run_isolated`, through ``os.wait4``).
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from pathlib import Path

import numpy as np

from dpcbench.bench.core.atomic import atomic_write_text
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.datasets import load_run_sequence
from dpcbench.bench.execution.provenance import (
    d2_normals_source,
    environment,
    is_complete_run_folder,
    read_run_folder,
    write_run_folder,
)
from dpcbench.bench.experiment.config import RunSpec
from dpcbench.bench.experiment.records import now_iso, run_record  # light (no pandas): created_at is the run's start
from dpcbench.holes.lazy import import_entry

WORKER_FLAG = "--worker"
_LIVE_PROCESSES: set = set()
_LIVE_LOCK = threading.Lock()


# -- memory --------------------------------------------------------------------------------
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


# -- CPU time ------------------------------------------------------------------------------------
def _cpu_seconds(usage) -> float:
    return float(usage.ru_utime + usage.ru_stime)


def process_cpu_s() -> float:
    """CPU seconds (user + system) used so far by this process (all its threads) and by its
    terminated, waited-for children (``getrusage`` RUSAGE_SELF + RUSAGE_CHILDREN)."""
    return _cpu_seconds(resource.getrusage(resource.RUSAGE_SELF)) + \
        _cpu_seconds(resource.getrusage(resource.RUSAGE_CHILDREN))


# -- producing the frames ----------------------------------------------------------------------
def _inpaint_timed(method, frames: list[np.ndarray], regions, colours: list[np.ndarray] | None = None,
                   fill: str = "auto") -> tuple[list[np.ndarray], list | None, list[dict], dict, list | None]:
    """Run the method (`inpaint_with_sources`: ``inpaint``'s output and the source of each copied point, which the
    colour fill needs; `inpaint_with_colours` when ``colours`` are given and the method colours its output itself,
    `methods.base.colours_itself`, its time then including its colours); per-frame timing for frame-independent
    methods, one timing otherwise.

    Returns (outputs, sources or None, per-frame timings, total timing, the method's colours or None)."""
    from dpcbench.methods.base import colours_itself

    own = colours is not None and colours_itself(method)

    def call(frames_, regions_, colours_):
        if own:
            out_, cols_ = method.inpaint_with_colours(frames_, colours_, regions_, fill=fill)
            return out_, None, cols_
        return (*method.inpaint_with_sources(frames_, regions_), None)

    per_frame: list[dict] = []
    if not getattr(method, "uses_neighbour_frames", False):
        out, sources, cols = [], [], []
        for i, frame in enumerate(frames):
            _reset_peak_rss()
            c0, t0 = process_cpu_s(), time.perf_counter()
            result, source, col = call([frame], None if regions is None else [regions[i]],
                                       None if colours is None else [colours[i]])
            per_frame.append({"frame": i, "time_s": time.perf_counter() - t0, "cpu_time_s": process_cpu_s() - c0,
                              "peak_mem_mb": peak_rss_mb()})
            out.append(result[0])
            cols.append(None if col is None else col[0])
            # a one-frame call's source frame 0 is frame i of the sequence
            sources.append(None if source is None or source[0] is None
                           else (np.where(source[0][0] >= 0, i, -1), source[0][1]))
        total = {"time_s": sum(p["time_s"] for p in per_frame), "cpu_time_s": sum(p["cpu_time_s"] for p in per_frame),
                 "peak_mem_mb": max(p["peak_mem_mb"] for p in per_frame)}
        return out, (sources if any(s is not None for s in sources) else None), per_frame, total, \
            (cols if own else None)
    _reset_peak_rss()
    c0, t0 = process_cpu_s(), time.perf_counter()
    out, sources, cols = call(frames, regions, colours)
    total = {"time_s": time.perf_counter() - t0, "cpu_time_s": process_cpu_s() - c0, "peak_mem_mb": peak_rss_mb()}
    return list(out), sources, per_frame, total, cols


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


def _check_colours(colours: list, outputs: list[np.ndarray], name: str) -> list[np.ndarray]:
    """The colours a method returned for its ``outputs``, as (N'_f, 3) uint8; ValueError when they do not match."""
    if len(colours) != len(outputs):
        raise ValueError(f"method {name} returned colours for {len(colours)} frames, points for {len(outputs)}")
    checked = []
    for i, (col, points) in enumerate(zip(colours, outputs)):
        col = np.asarray(col)
        if col.shape != (len(points), 3) or col.dtype != np.uint8:
            raise ValueError(f"method {name} returned invalid colours for frame {i} (shape {col.shape}, dtype "
                             f"{col.dtype}; must be ({len(points)}, 3) uint8)")
        checked.append(col)
    return checked


def produce_frames(spec: RunSpec, truth, run_dir: Path) -> None:
    """Damage, inpaint, and write the run folder atomically (`bench.execution.provenance.write_run_folder`)."""
    from dpcbench.holes.regions import regions_to_json

    frames = truth.points
    colors = truth.colors if all(c is not None for c in truth.colors) else None
    generator = import_entry(spec.holes["entry"])(**spec.holes["params"])
    damage = generator.damage(frames, spec.holes["seed"], colors=colors)
    mode = spec.protocol.get("regions", "given")
    detected, detect_time = None, 0.0
    if mode == "given":
        regions = damage.regions
    elif mode == "detected":
        from dpcbench.holes.detection import detect_holes

        t0 = time.perf_counter()
        detected = [detect_holes(f, **spec.protocol.get("detection", {})) for f in damage.frames]
        detect_time = time.perf_counter() - t0
        regions = detected
    else:
        regions = None
    method = import_entry(spec.method["entry"])(**spec.method["params"])
    colour_fill = spec.protocol.get("colour_fill", "auto")
    inpainted, sources, per_frame, total, inpainted_colors = _inpaint_timed(method, damage.frames, regions,
                                                                             damage.colors, colour_fill)
    inpainted = _check_output(inpainted, damage.frames, spec.method["name"])
    if inpainted_colors is not None:
        inpainted_colors = _check_colours(inpainted_colors, inpainted, spec.method["name"])
    elif damage.colors is not None:
        # the method's colours as `dpcbench inpaint --colour` gives them (the experiment's colour_fill, default
        # "auto": kept points keep theirs, copied points their source's, the rest a harmonic fill from the rim)
        from dpcbench.methods._colour import colour_outputs

        t0 = time.perf_counter()
        inpainted_colors = colour_outputs(damage.frames, damage.colors, inpainted, sources, colour_fill)
        total = {**total, "colour_time_s": time.perf_counter() - t0}

    holes = regions_to_json(damage.regions, generator=spec.holes["generator"], params=spec.holes["params"],
                            seed=spec.holes["seed"],
                            per_frame=[{"removed_fraction": float(m.mean())} for m in damage.removed])
    manifest = {"inpaint_key": spec.inpaint_key, "spec": spec.identity(), "frames": len(frames),
                "points": [len(f) for f in frames], "per_frame": per_frame, "total": total,
                "removed_fraction": [float(m.mean()) for m in damage.removed], "regions_mode": mode,
                "detect_time_s": detect_time, "created_by_pid": os.getpid(),
                # every parameter as the method resolved it (a variant's switches included)
                "method_params_resolved": method.get_params()}
    # --force, or another worker finished the same frames first: the folder is replaced
    write_run_folder(run_dir, damaged=damage.frames, damaged_colors=damage.colors, inpainted=inpainted,
                     inpainted_colors=inpainted_colors, holes=holes,
                     detected=None if detected is None else regions_to_json(detected, detector="dpcbench.holes.detection"),
                     manifest=manifest)


# -- scoring ---------------------------------------------------------------------------------
def _peak_label(peak) -> str:
    if isinstance(peak, str):
        return peak
    return str(int(peak)) if float(peak) == int(peak) else repr(float(peak))


def _uses_peak(name: str) -> bool:
    """Whether the metric's value depends on the PSNR peak (`metrics.registry`, the one source)."""
    from dpcbench.metrics.registry import describe

    metric = describe(name)
    return metric is not None and metric.uses_peak


def score_run(spec: RunSpec, truth, inpainted: list[np.ndarray], regions: list,
              inpainted_colors: list | None = None) -> list[dict]:
    """Every metric per frame and scope (and peak for PSNRs), plus temporal consistency at frame -1.

    PSNRs are as `metrics.score_pair` returns them (capped at its ``max_psnr``, 200 dB by default,
    when a result equals the reference). D2 uses the ground truth's own normals when its frames carry
    them (`d2_normals_source`), else normals estimated by PCA of 12 neighbours. The colour metrics
    (``cpsnr_*``) score the result's colours (``inpainted_colors``) against the ground truth's; on a
    sequence without colours they are left out (no row: a report says the sequence has none)."""
    import dpcbench.metrics as metrics_pkg

    cfg = spec.metrics
    coloured = inpainted_colors is not None and all(c is not None for c in truth.colors)
    names = [n for n in cfg["names"] if coloured or not n.startswith("cpsnr_")]
    peak_names = [n for n in names if _uses_peak(n)]
    rows: list[dict] = []
    for f, (cloud, result) in enumerate(zip(truth.frames, inpainted)):
        # one CloudPair per frame: its KD-trees and neighbour queries serve every scope and peak
        pair = metrics_pkg.make_pair(cloud.points, result, cloud.normals,
                                     reference_colours=cloud.colors if coloured else None,
                                     result_colours=inpainted_colors[f] if inpainted_colors and coloured else None)
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

    outcome: {"run_id", "status": "done", "record": {...run facts: `RunRecord.facts`...}, "results": [rows]}
    Raises on any failure (the worker wrapper turns that into a "failed" outcome).
    """
    c0, t0 = process_cpu_s(), time.perf_counter()
    created = now_iso()
    run_dir = Path(runs_dir) / spec.inpaint_key
    truth = load_run_sequence(spec.sequence)
    if force or not is_complete_run_folder(run_dir) or not _has_checksums(run_dir) or _lacks_colours(run_dir, truth):
        # a folder without checksums, or without the colours of coloured data (an older dpcbench), is made anew
        produce_frames(spec, truth, run_dir)
        reused = False
    else:
        reused = True
    folder = read_run_folder(run_dir)  # checksums and inpaint_key verified
    if folder["manifest"].get("inpaint_key") != spec.inpaint_key:
        raise ValueError(f"{run_dir}: its manifest is of run folder {folder['manifest'].get('inpaint_key')}, not "
                         f"{spec.inpaint_key}; remove the folder or rerun with --force")
    if len(folder["inpainted"]) != len(truth.frames):
        raise ValueError(f"{run_dir}: holds {len(folder['inpainted'])} frames, the sequence has {len(truth.frames)}; "
                         "rerun with --force")
    # without removed points (the data's own holes) there is no ground truth apart from the input
    # itself: no quality scores
    removes_points = import_entry(spec.holes["entry"]).removes_points
    results = (score_run(spec, truth, folder["inpainted"], folder["regions"], folder["inpainted_colors"])
               if removes_points else [])
    manifest = folder["manifest"]
    # cpu_time_s only where the run folder measured it (folders written before it was added lack it)
    for entry in [*manifest["per_frame"], {"frame": -1, **manifest["total"]}]:
        for metric in ("time_s", "cpu_time_s", "peak_mem_mb"):
            if entry.get(metric) is not None:
                results.append({"frame": entry["frame"], "metric": metric, "scope": "frame", "peak": "",
                                "value": entry[metric]})
    for f, frac in enumerate(manifest["removed_fraction"]):
        results.append({"frame": f, "metric": "removed_fraction", "scope": "frame", "peak": "", "value": frac})
    env = environment()
    env["frames_reused"] = reused
    env["d2_normals"] = d2_normals_source(truth)
    record = run_record(spec, status="done", code_version=env["git_commit"], wall_time_s=time.perf_counter() - t0,
                        cpu_time_s=process_cpu_s() - c0, peak_mem_mb=manifest["total"]["peak_mem_mb"], env=env,
                        created_at=created, finished_at=now_iso(), output_dir=str(run_dir))
    return {"run_id": spec.run_id, "status": "done", "record": record.facts(), "results": results}


def _lacks_colours(run_dir: Path, truth) -> bool:
    """Whether the sequence has colours but the run folder's inpainted frames do not (written before runs
    coloured their output)."""
    if not all(c is not None for c in truth.colors):
        return False
    from dpcbench.bench.data.plyio import read_ply

    first = run_dir / "inpainted" / "frame_0000.ply"
    try:
        return read_ply(first).colors is None
    except (OSError, ValueError, UserError):
        return False  # a damaged folder: `read_run_folder`'s checksums say so


def _has_checksums(run_dir: Path) -> bool:
    """Whether the run folder's manifest records the checksums of its files (`provenance.folder_checksums`)."""
    try:
        return "sha256" in json.loads((run_dir / "manifest.json").read_text())
    except (OSError, ValueError):
        return False


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
    c0, t0 = process_cpu_s(), time.perf_counter()
    try:
        outcome = execute_run(spec, runs_dir, force=force)
    except BaseException as err:  # every failure becomes a recorded message
        tb = traceback.format_exc()
        # timed like a finished run (the same span), so that a sweep's cost counts its failures too
        outcome = {"run_id": spec.run_id, "status": "failed", "error": f"{type(err).__name__}: {err}",
                   "traceback": tb[-4000:], "wall_time_s": time.perf_counter() - t0,
                   "cpu_time_s": process_cpu_s() - c0}
    atomic_write_text(out_path, json.dumps(outcome, default=float))
    return 0


def _tail(path: Path, lines: int = 12) -> str:
    try:
        text = path.read_text(errors="replace").strip().splitlines()
    except OSError:
        return ""
    return "\n".join(text[-lines:])


def _wait_with_usage(proc: subprocess.Popen, timeout_s: float):
    """Wait for ``proc`` like ``proc.wait(timeout_s)`` (``subprocess.TimeoutExpired`` past it) and
    return the child's resource usage (``os.wait4``: its CPU time, all threads and waited-for
    grandchildren), or None where ``os.wait4`` does not exist (then only ``proc.wait`` is done).

    Why not ``proc.wait``: it reaps the child without its usage, and ``getrusage(RUSAGE_CHILDREN)``
    in the driver sums every worker of a pool. The polling mirrors ``Popen.wait``'s (a delay that
    doubles up to 50 ms)."""
    if not hasattr(os, "wait4"):
        proc.wait(timeout=timeout_s)
        return None
    deadline = time.monotonic() + timeout_s
    delay = 0.0005
    while True:
        try:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        except ChildProcessError:  # reaped by Popen.poll in another thread (kill_live_workers)
            proc.wait()
            return None
        if pid == proc.pid:
            proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen must not wait again
            return usage
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise subprocess.TimeoutExpired(proc.args, timeout_s)
        time.sleep(min(delay, remaining))
        delay = min(delay * 2, 0.05)


def _kill_and_reap(proc: subprocess.Popen):
    """Kill ``proc`` and reap it; its resource usage as `_wait_with_usage` gives it."""
    proc.kill()
    if proc.returncode is not None:
        return None
    if not hasattr(os, "wait4"):
        proc.wait()
        return None
    try:
        _, status, usage = os.wait4(proc.pid, 0)
    except ChildProcessError:  # reaped by Popen.poll in another thread (kill_live_workers)
        proc.wait()
        return None
    proc.returncode = os.waitstatus_to_exitcode(status)
    return usage


def run_isolated(spec_dict: dict, runs_dir: str, force: bool = False, threads: int | None = None) -> dict:
    """Run one spec in a fresh ``python -m dpcbench.bench.execution.worker --worker`` process with the spec's timeout.

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
        cmd = [sys.executable, "-m", "dpcbench.bench.execution.worker", WORKER_FLAG, str(spec_path), str(out_path), str(runs)]
        if force:
            cmd.append("--force")
        t0 = time.perf_counter()
        with open(log_path, "w") as log:
            proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
            with _LIVE_LOCK:
                _LIVE_PROCESSES.add(proc)
            try:
                usage = _wait_with_usage(proc, spec.timeout_s)
                timed_out = False
            except subprocess.TimeoutExpired:
                usage = _kill_and_reap(proc)
                timed_out = True
            except BaseException:  # Ctrl-C in the driver: the worker goes with it
                _kill_and_reap(proc)
                raise
            finally:
                with _LIVE_LOCK:
                    _LIVE_PROCESSES.discard(proc)
        elapsed = time.perf_counter() - t0
        # a worker that could not report is timed here, over its whole process (start-up included)
        base = {"run_id": spec.run_id, "status": "failed", "wall_time_s": elapsed,
                "cpu_time_s": None if usage is None else _cpu_seconds(usage), "log": str(log_path)}
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


if __name__ == "__main__":
    if len(sys.argv) >= 5 and sys.argv[1] == WORKER_FLAG:
        sys.exit(worker_main(sys.argv[2], sys.argv[3], sys.argv[4], "--force" in sys.argv[5:]))
    print("usage: python -m dpcbench.bench.execution.worker --worker SPEC_JSON OUTCOME_JSON RUNS_DIR [--force]", file=sys.stderr)
    sys.exit(2)
