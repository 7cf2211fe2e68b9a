"""Executor throughput and the cost of the paper protocol at scale: measured figures, printed.

Three subcommands (each prints a table and can save JSON; the third only computes from the JSON):

    # 1. runs per minute of one fixed grid (THROUGHPUT_GRID: 18 runs on tiny stand-ins) for serial,
    #    pool x2, Dask LocalCluster x1 / x2 and --scheduler tcp:// against a `dask scheduler` +
    #    2 `dask worker` processes this script starts and stops; plus the per-run cost and the Dask
    #    scheduler's per-task overhead (no-op tasks and the sweep difference against serial)
    python tests/benchmarks/executor_throughput.py grid --repeats 2 --json grid.json

    # 2. per-frame cost of every paper column at default size: one run per (stand-in, column), a
    #    few frames, one hole configuration, serial; method time per frame from the runs' own
    #    ``time_s`` rows, scoring and loading as the rest of the run's wall time
    python tests/benchmarks/executor_throughput.py paper-costs --frames 2 --json costs.json

    # 3. the projection: the paper preset at F frames a sequence on M machines x W workers
    python tests/benchmarks/executor_throughput.py project --grid grid.json --costs costs.json \\
        --frames 300 --machines 10 --workers-per-machine 2

Every timing is the wall time of the whole sweep as `bench.execution.runner.run_experiment` does it (worker
process per run, stand-ins loaded from the disk cache, scoring), the minimum over ``--repeats``.
The machine this runs on may be shared: give the load average with the figures (printed).
"""

from __future__ import annotations

import argparse
import heapq
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

#: the fixed grid for runs per minute: 2 stand-ins x 3 seeds x 3 cheap methods = 18 runs of 2 tiny
#: frames each; cheap methods so that the executor's own cost is a visible share of a run
THROUGHPUT_GRID = {
    "experiment": {"name": "throughput", "timeout_s": 600, "regions": "given"},
    "sequences": [{"name": "human", "params": {"size": "tiny"}, "frames": 2},
                  {"name": "bunny", "params": {"size": "tiny"}, "frames": 2}],
    "holes": [{"generator": "region", "params": {"preset": "medium", "count": 2, "coherent": True},
               "seeds": [0, 1, 2]}],
    "methods": [{"name": "none"}, {"name": "temporal-copy"}, {"name": "lozes-pde"}],
    "metrics": {"names": ["gpsnr_d1", "nshd"], "peaks": ["intrinsic"], "scopes": ["frame", "holes"]},
}

EXECUTOR_SETUPS = {  # name -> (executor, jobs, needs a tcp cluster)
    "serial": ("serial", 1, False),
    "pool2": ("pool", 2, False),
    "dask1": ("dask", 1, False),
    "dask2": ("dask", 2, False),
    "tcp2": ("dask", 2, True),
}


def load_average() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def _sweep(cfg: dict, executor: str, jobs: int, scheduler: str | None, workdir: Path) -> tuple[float, object]:
    """Wall time of one sweep of ``cfg`` into a fresh store and run folder; returns (seconds, store)."""
    from dpcbench.bench.execution.runner import run_experiment
    from dpcbench.bench.experiment.config import parse_config
    from dpcbench.bench.results.store import ResultsStore

    if workdir.exists():
        shutil.rmtree(workdir)
    workdir.mkdir(parents=True)
    specs = parse_config(cfg).expand()
    store = ResultsStore(workdir / "store.sqlite")
    t0 = time.perf_counter()
    summary = run_experiment(specs, store, executor=executor, jobs=jobs, scheduler=scheduler, quiet=True,
                             runs_dir=workdir / "runs")
    wall = time.perf_counter() - t0
    if summary.failed:
        raise SystemExit(f"{len(summary.failed)} run(s) failed under {executor}: {summary.errors}")
    return wall, store


class TcpCluster:
    """`dask scheduler` + ``n`` single-threaded `dask worker` processes on this machine (context manager)."""

    def __init__(self, n_workers: int, workdir: Path):
        self.n_workers = n_workers
        self.workdir = workdir
        self.procs: list[subprocess.Popen] = []
        self.address = ""
        self.start_s = 0.0

    def __enter__(self):
        from distributed import Client

        dask = Path(sys.executable).parent / "dask"
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
        self.workdir.mkdir(parents=True, exist_ok=True)
        sched_file = self.workdir / "scheduler.json"
        sched_file.unlink(missing_ok=True)
        t0 = time.perf_counter()
        self.procs.append(subprocess.Popen([str(dask), "scheduler", "--scheduler-file", str(sched_file), "--port", "0",
                                           "--no-dashboard", "--host", "127.0.0.1"], cwd=REPO, env=env,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        while not sched_file.exists():
            if time.perf_counter() - t0 > 60:
                raise RuntimeError("dask scheduler did not start in 60 s")
            time.sleep(0.1)
        self.address = json.loads(sched_file.read_text())["address"]
        for i in range(self.n_workers):
            self.procs.append(subprocess.Popen([str(dask), "worker", self.address, "--nthreads", "1", "--no-dashboard",
                                               "--local-directory", str(self.workdir / f"w{i}")], cwd=REPO, env=env,
                                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        with Client(self.address, timeout="30s") as client:
            client.wait_for_workers(self.n_workers, timeout=120)
        self.start_s = time.perf_counter() - t0
        return self

    def __exit__(self, *exc):
        for proc in reversed(self.procs):
            proc.terminate()
        for proc in self.procs:
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()


def _noop(i):
    return i


def scheduler_overhead(address: str, n_tasks: int = 300) -> dict:
    """Per-task cost of the Dask scheduler on a running cluster: a sequential round trip (submit one
    no-op task, wait for it; what a run pays on top of its own time) and the throughput of a batch
    of no-op tasks spread over the workers."""
    from distributed import Client

    with Client(address, timeout="30s") as client:
        client.submit(_noop, -1, pure=False).result()  # warm: function shipped, connections open
        rounds = []
        for i in range(50):
            t0 = time.perf_counter()
            client.submit(_noop, i, pure=False).result()
            rounds.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        client.gather(client.map(_noop, range(n_tasks), pure=False))
        batch = (time.perf_counter() - t0) / n_tasks
    rounds.sort()
    return {"round_trip_min_s": rounds[0], "round_trip_median_s": rounds[len(rounds) // 2], "batch_per_task_s": batch}


def cmd_grid(args) -> dict:
    setups = args.executors.split(",")
    for name in setups:
        if name not in EXECUTOR_SETUPS:
            raise SystemExit(f"unknown setup {name!r}; choose from {', '.join(EXECUTOR_SETUPS)}")
    from dpcbench.bench.experiment.config import parse_config

    n_runs = len(parse_config(THROUGHPUT_GRID).expand())
    root = Path(tempfile.mkdtemp(prefix="dpcbench-throughput-"))
    out: dict = {"n_runs": n_runs, "grid": THROUGHPUT_GRID, "setups": {}, "load_before": load_average()}
    try:
        # warm the stand-in cache so that no setup pays the generation
        _sweep({**THROUGHPUT_GRID, "methods": [{"name": "none"}],
                "holes": [{**THROUGHPUT_GRID["holes"][0], "seeds": [0]}]}, "serial", 1, None, root / "warm")
        tcp = None
        if any(EXECUTOR_SETUPS[s][2] for s in setups):
            tcp = TcpCluster(2, root / "tcp").__enter__()
            out["tcp_cluster_start_s"] = tcp.start_s
            out["scheduler_overhead_tcp2"] = scheduler_overhead(tcp.address)
            print(f"  tcp cluster up in {tcp.start_s:.1f} s; no-op tasks: {out['scheduler_overhead_tcp2']}", flush=True)
        try:
            for name in setups:
                executor, jobs, needs_tcp = EXECUTOR_SETUPS[name]
                walls = []
                for rep in range(args.repeats):
                    wall, store = _sweep(THROUGHPUT_GRID, executor, jobs, tcp.address if needs_tcp else None,
                                         root / f"{name}-{rep}")
                    walls.append(wall)
                    print(f"  {name} repeat {rep}: {wall:.1f} s (load {load_average()})", flush=True)
                runs = store.runs_frame()
                out["setups"][name] = {"walls_s": walls, "min_wall_s": min(walls), "runs_per_min": n_runs / min(walls) * 60,
                                       "in_worker_run_s_mean": float(runs.wall_time_s.mean())}
        finally:
            if tcp is not None:
                tcp.__exit__(None, None, None)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    out["load_after"] = load_average()
    s = out["setups"]
    if "serial" in s:
        serial = s["serial"]
        serial["per_run_s"] = serial["min_wall_s"] / n_runs
        # what a worker process costs on top of the run it does (start python, import, report back)
        serial["process_overhead_s"] = serial["per_run_s"] - serial["in_worker_run_s_mean"]
        for name in ("dask1",):
            if name in s:
                s[name]["overhead_vs_serial_per_run_s"] = (s[name]["min_wall_s"] - serial["min_wall_s"]) / n_runs
    print(f"\ngrid: {n_runs} runs (2 tiny stand-ins x 3 seeds x none/temporal-copy/lozes-pde, 2 frames each); "
          f"min of {args.repeats}; load before {out['load_before']}, after {out['load_after']}")
    print(f"{'setup':8s} {'min wall s':>10s} {'runs/min':>9s} {'in-worker s/run':>16s}")
    for name, v in s.items():
        print(f"{name:8s} {v['min_wall_s']:10.1f} {v['runs_per_min']:9.1f} {v['in_worker_run_s_mean']:16.2f}")
    if "serial" in s:
        print(f"serial per-run cost {s['serial']['per_run_s']:.2f} s, of which worker-process overhead "
              f"{s['serial']['process_overhead_s']:.2f} s")
    if "dask1" in s and "serial" in s:
        print(f"Dask LocalCluster x1 vs serial: {s['dask1']['overhead_vs_serial_per_run_s']:+.2f} s a run "
              "(cluster start included)")
    if "scheduler_overhead_tcp2" in out:
        o = out["scheduler_overhead_tcp2"]
        print(f"tcp cluster start {out['tcp_cluster_start_s']:.1f} s; no-op task round trip min "
              f"{o['round_trip_min_s'] * 1e3:.2f} ms, median {o['round_trip_median_s'] * 1e3:.2f} ms; batch "
              f"{o['batch_per_task_s'] * 1e3:.2f} ms a task")
    return out


class WorkerCpuPoller:
    """Samples, once a second, the CPU time (user + system, /proc/PID/stat) of every run worker process
    (``python -m dpcbench.bench.execution.runner --worker``) whose command line names ``runs_dir``; keeps the last sample
    per run id. On a shared machine a run's wall time measures the load, its CPU time the run (Linux only)."""

    def __init__(self, runs_dir: Path):
        import threading

        self.runs_dir = str(runs_dir)
        self.cpu_s: dict[str, float] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, daemon=True)

    def _poll(self):
        tick = os.sysconf("SC_CLK_TCK")
        while not self._stop.is_set():
            for proc in Path("/proc").glob("[0-9]*"):
                try:
                    cmd = (proc / "cmdline").read_text().split("\0")
                    if "--worker" not in cmd or self.runs_dir not in cmd:
                        continue
                    spec = json.loads(Path(cmd[cmd.index("--worker") + 1]).read_text())
                    fields = (proc / "stat").read_text().rsplit(")", 1)[1].split()
                    self.cpu_s[spec["run_id"]] = (int(fields[11]) + int(fields[12])) / tick
                except (OSError, ValueError, KeyError, IndexError):
                    continue  # the process ended between listing and reading
            self._stop.wait(1.0)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def cmd_paper_costs(args) -> dict:
    from dpcbench.bench.experiment.config import parse_config
    from dpcbench.bench.reporting.paper import table_methods

    seqs = args.sequences.split(",")
    cfg = {
        "experiment": {"name": "paper-costs", "timeout_s": 7200, "regions": "given"},
        "sequences": [{"name": s, "params": {"size": args.size}, "frames": args.frames} for s in seqs],
        "holes": [{"generator": "region", "params": {"preset": "medium", "count": 3, "coherent": True}, "seeds": [0]}],
        "methods": [{k: v for k, v in m.items()} for m in table_methods()],
        "metrics": {"names": ["gpsnr_d1", "gpsnr_d2", "nshd", "hausdorff", "chamfer"], "peaks": ["intrinsic", 1023],
                    "scopes": ["frame", "holes"], "temporal_consistency": True},
    }
    if args.columns:
        wanted = set(args.columns.split(","))
        cfg["methods"] = [m for m in cfg["methods"] if m["label"] in wanted or m["name"] in wanted]
    from dpcbench.bench.data.datasets import load_dataset

    load_before = load_average()
    gen = {}
    for s in seqs:  # generation (or cache read) of the frames, timed apart from the runs
        t0 = time.perf_counter()
        seq = load_dataset(s, frames=args.frames, size=args.size)
        gen[s] = {"load_s": time.perf_counter() - t0, "points": [len(f) for f in seq.points]}
    workdir = Path(args.workdir or tempfile.mkdtemp(prefix="dpcbench-papercosts-"))
    with WorkerCpuPoller((workdir / "runs").resolve()) as poller:
        wall, store = _sweep(cfg, "serial", 1, None, workdir)
    runs = store.runs_frame()
    res = store.results_frame()
    times = res[(res.metric == "time_s") & (res.scope == "frame")]
    specs = {s.run_id: s for s in parse_config(cfg).expand()}
    from dpcbench.bench.reporting.paper import column_label

    rows = []
    for _, run in runs.iterrows():
        spec = specs[run.run_id]
        t = times[times.run_id == run.run_id]
        method_total = float(t[t.frame == -1].value.iloc[0])
        rows.append({"sequence": spec.sequence["name"], "column": column_label(spec.method["name"], spec.method["params"]),
                     "frames": args.frames, "run_wall_s": float(run.wall_time_s), "method_s": method_total,
                     "method_per_frame_s": method_total / args.frames,
                     "rest_per_frame_s": (float(run.wall_time_s) - method_total) / args.frames,
                     # the whole worker process (load, damage, method, write, score), sampled each second
                     "run_cpu_s": poller.cpu_s.get(run.run_id)})
    # the parts of a run other than the method, timed again in this process in CPU time: the stand-in's
    # frames read from the cache, the damage, the scoring of the run's frames as written (every metric
    # x peak x scope + temporal consistency), and a worker process's start (interpreter + imports)
    parts = _run_part_costs(specs, runs, workdir / "runs")
    for r, run_id in zip(rows, runs.run_id):
        part = parts[run_id]
        r.update({k: part[k] for k in ("load_cpu_s", "damage_cpu_s", "score_cpu_s", "start_cpu_s")})
        r["score_cpu_per_frame_s"] = part["score_cpu_s"] / args.frames
        if r["run_cpu_s"] is not None:
            rest = part["load_cpu_s"] + part["damage_cpu_s"] + part["score_cpu_s"] + part["start_cpu_s"]
            r["method_cpu_per_frame_s"] = (r["run_cpu_s"] - rest) / args.frames
            # a run of F frames: the process start once, then F x (load, damage, method, write, scoring)
            r["cpu_per_frame_s"] = (r["run_cpu_s"] - part["start_cpu_s"]) / args.frames
    out = {"size": args.size, "frames": args.frames, "sweep_wall_s": wall, "generation": gen, "runs": rows,
           "load_before": load_before, "load_after": load_average()}
    out["paper_preset"] = project_paper_preset(rows)
    print(f"\nper-frame cost at size={args.size}, {args.frames} frames a run, serial, 1 run each "
          f"(load before {load_before}, after {out['load_after']})")
    for s, g in gen.items():
        print(f"  {s}: {g['points']} points; load/generate {g['load_s']:.1f} s")
    print("wall times (inflated by other load); CPU times (user + system): the run's worker process, sampled each "
          "second, and its scoring, re-timed here")
    print(f"{'sequence':8s} {'column':32s} {'method s/frame':>14s} {'rest s/frame':>12s} {'run wall s':>10s} "
          f"{'run CPU s':>9s} {'method CPU/frame':>16s} {'score CPU/frame':>15s}")
    for r in rows:
        cpu = f"{r['run_cpu_s']:9.1f}" if r["run_cpu_s"] is not None else f"{'-':>9s}"
        mcpu = f"{r['method_cpu_per_frame_s']:16.2f}" if "method_cpu_per_frame_s" in r else f"{'-':>16s}"
        print(f"{r['sequence']:8s} {r['column']:32s} {r['method_per_frame_s']:14.2f} {r['rest_per_frame_s']:12.2f} "
              f"{r['run_wall_s']:10.1f} {cpu} {mcpu} {r['score_cpu_per_frame_s']:15.2f}")
    for s, g in parts["_sequences"].items():
        print(f"  {s}: per run, CPU s: load {g['load_cpu_s']:.2f}, damage {g['damage_cpu_s']:.2f}, worker start "
              f"{g['start_cpu_s']:.2f}")
    proj = out["paper_preset"]
    if proj:
        print(f"\npaper preset projection from these CPU times (not a run): {proj['runs']} runs of {proj['frames']} "
              f"frames, {proj['total_cpu_h']:.2f} CPU-h; on {proj['slots']} cores {proj['makespan_h']:.2f} h "
              f"(longest-first schedule of whole runs; assumes two runs at once each keep a core)")
        for col, v in proj["per_column_cpu_h"].items():
            print(f"  {col:32s} {v:6.2f} CPU-h")
    if not args.workdir:
        shutil.rmtree(workdir, ignore_errors=True)
    return out


def _cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _run_part_costs(specs: dict, runs, runs_dir: Path) -> dict:
    """CPU seconds of the parts of each run besides its method, timed in this process: per sequence the
    frames' load (`load_run_sequence`, from the disk cache), the damage, and a worker process's start
    (``python -c 'import dpcbench.bench.execution.worker'``, child CPU); per run the scoring of its folder
    (`bench.execution.worker.score_run`, as the worker does it)."""
    from dpcbench.bench.data.datasets import load_run_sequence
    from dpcbench.bench.execution.provenance import read_run_folder
    from dpcbench.bench.execution.worker import score_run
    from dpcbench.holes.lazy import import_entry

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", "import dpcbench.bench.execution.worker, dpcbench.metrics"], check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    truths: dict[str, tuple] = {}
    out: dict = {"_sequences": {}}
    for run_id in runs.run_id:
        spec = specs[run_id]
        key = spec.sequence_label
        if key not in truths:
            c0 = _cpu_s()
            truth = load_run_sequence(spec.sequence)
            c1 = _cpu_s()
            import_entry(spec.holes["entry"])(**spec.holes["params"]).damage(truth.points, spec.holes["seed"])
            c2 = _cpu_s()
            truths[key] = (truth, c1 - c0, c2 - c1)
            out["_sequences"][key] = {"load_cpu_s": c1 - c0, "damage_cpu_s": c2 - c1, "start_cpu_s": start}
        truth, load, dmg = truths[key]
        folder = read_run_folder(runs_dir / spec.inpaint_key)
        c0 = _cpu_s()
        score_run(spec, truth, folder["inpainted"], folder["regions"])
        out[run_id] = {"load_cpu_s": load, "damage_cpu_s": dmg, "score_cpu_s": _cpu_s() - c0, "start_cpu_s": start}
    return out


def project_paper_preset(rows: list[dict], frames: int = 10, hole_configs: int = 2, seeds: int = 3,
                         cores: int = 2) -> dict | None:
    """The full `paper` preset (bench/presets/paper.toml: each measured sequence x ``hole_configs`` x
    ``seeds`` x each column, ``frames`` frames a run) from the measured CPU per frame: a run costs
    start + frames x cpu_per_frame. Wall time on ``cores`` cores: `makespan` of the runs (two runs at
    once, each on its own core: the ideal, which a loaded machine does not reach). None without CPU samples."""
    if not rows or any("cpu_per_frame_s" not in r for r in rows):
        return None
    durations, per_column = [], {}
    for r in rows:
        run = r["start_cpu_s"] + frames * r["cpu_per_frame_s"]
        durations += [run] * (hole_configs * seeds)
        per_column[r["column"]] = per_column.get(r["column"], 0.0) + run * hole_configs * seeds / 3600
    return {"frames": frames, "runs": len(durations), "total_cpu_h": sum(durations) / 3600, "slots": cores,
            "makespan_h": makespan(durations, cores) / 3600, "per_column_cpu_h": per_column}


def makespan(durations: list[float], slots: int) -> float:
    """Longest-processing-time-first list scheduling of independent runs onto ``slots`` workers (what
    a Dask scheduler with as many idle single-threaded workers does with a queue it is given at
    once, up to its own ordering): the finishing time of the last run."""
    loads = [0.0] * slots
    heapq.heapify(loads)
    for d in sorted(durations, reverse=True):
        heapq.heappush(loads, heapq.heappop(loads) + d)
    return max(loads)


def cmd_project(args) -> dict:
    grid = json.loads(Path(args.grid).read_text())
    costs = json.loads(Path(args.costs).read_text())
    s = grid["setups"]
    process_overhead = s["serial"]["process_overhead_s"]
    task_overhead = grid["scheduler_overhead_tcp2"]["round_trip_median_s"]
    # a machine with W workers delivers (its W-worker rate / its serial rate) runs' worth of serial work
    speedup = s["dask2"]["runs_per_min"] / s["serial"]["runs_per_min"] if "dask2" in s else 1.0
    if args.speedup is not None:  # e.g. when the grid's setups ran under different loads
        speedup = args.speedup
    per_frame = {}
    for r in costs["runs"]:
        # CPU time of the run where sampled (wall time on a loaded machine measures the load), else wall
        whole = r.get("run_cpu_s") if args.use_cpu and r.get("run_cpu_s") else r["run_wall_s"]
        per_frame.setdefault(r["column"], {})[r["sequence"]] = whole / r["frames"]
    seqs = sorted({r["sequence"] for r in costs["runs"]})
    n_seq_configs = args.sequences
    hole_configs, seeds = 2, 3  # bench/presets/paper.toml: independent and coherent holes, seeds 0-2
    durations = []
    for by_seq in per_frame.values():
        for i in range(n_seq_configs):
            per = by_seq[seqs[i % len(seqs)]]  # further sequences cost like the measured stand-ins, in turn
            durations += [args.frames * per + process_overhead + task_overhead] * (hole_configs * seeds)
    slots = args.machines * args.workers_per_machine
    # runs sharing a machine slow each other down (memory bandwidth, the OS): with W workers a run takes
    # W / speedup_W times its serial time; speedup_2 is measured, 1 worker has none
    if args.workers_per_machine not in (1, 2):
        raise SystemExit("--workers-per-machine: only 1 or 2 are measured here")
    inflation = args.workers_per_machine / (speedup if args.workers_per_machine == 2 else 1.0)
    durations = [d * inflation for d in durations]
    total_work = sum(durations)
    longest = max(durations)
    ideal = total_work / slots
    lpt = makespan(durations, slots)
    out = {"runs": len(durations), "total_cpu_h": total_work / 3600, "longest_run_h": longest / 3600,
           "slots": slots, "measured_speedup_2_workers": speedup, "makespan_h": lpt / 3600,
           "ideal_h": ideal / 3600}
    print(f"\npaper preset: {n_seq_configs} sequences x {hole_configs} hole configurations x {seeds} seeds x "
          f"{len(per_frame)} columns = {len(durations)} runs of {args.frames} frames")
    print(f"per-frame cost (method + scoring + loading, s) at size={costs['size']}:")
    for col, by_seq in per_frame.items():
        print(f"  {col:32s} " + ", ".join(f"{q} {v:.1f}" for q, v in by_seq.items()))
    print(f"overheads a run: worker process {process_overhead:.2f} s, Dask task round trip {task_overhead * 1e3:.1f} ms")
    how = "given (--speedup)" if args.speedup is not None else "measured (dask2 / serial)"
    print(f"{args.machines} machines x {args.workers_per_machine} workers; 2-worker speedup on one machine "
          f"{speedup:.2f}, {how}")
    print(f"total work {total_work / 3600:.1f} worker-hours; longest single run {longest / 3600:.1f} h")
    print(f"projected wall time: {out['makespan_h']:.1f} h (perfect balance would give {out['ideal_h']:.1f} h; "
          "a run is the unit of scheduling, so the longest run bounds it)")
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("grid", help="runs per minute of each executor on THROUGHPUT_GRID")
    g.add_argument("--repeats", type=int, default=2)
    g.add_argument("--executors", default=",".join(EXECUTOR_SETUPS))
    g.add_argument("--json", default=None)
    c = sub.add_parser("paper-costs", help="per-frame cost of every paper column")
    c.add_argument("--size", default="default")
    c.add_argument("--frames", type=int, default=2)
    c.add_argument("--sequences", default="human,bunny")
    c.add_argument("--columns", default=None, help="comma-separated column labels or method names (default: all)")
    c.add_argument("--workdir", default=None)
    c.add_argument("--json", default=None)
    p = sub.add_parser("project", help="project the paper preset on a cluster from grid + paper-costs JSON")
    p.add_argument("--grid", required=True)
    p.add_argument("--costs", required=True)
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--sequences", type=int, default=5, help="sequences in the preset (the paper has 5)")
    p.add_argument("--machines", type=int, default=10)
    p.add_argument("--workers-per-machine", type=int, default=2)
    p.add_argument("--speedup", type=float, default=None,
                   help="runs' worth of serial work 2 workers on one machine deliver (default: measured dask2/serial)")
    p.add_argument("--use-cpu", action="store_true", help="per-run CPU time instead of wall time where sampled")
    p.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    out = {"grid": cmd_grid, "paper-costs": cmd_paper_costs, "project": cmd_project}[args.cmd](args)
    if getattr(args, "json", None):
        Path(args.json).write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
