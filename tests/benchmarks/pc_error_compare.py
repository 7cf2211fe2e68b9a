"""Our colour PSNR against MPEG's pc_error on real frames, and `dpcbench score` against pc_error in time (issue 54).
Not a test; needs a pc_error binary (mpeg-pcc-dmetric, built outside the project), skips without it.

    .venv/bin/python tests/benchmarks/pc_error_compare.py /path/to/pc_error              # figures
    nice -n 10 .venv/bin/python tests/benchmarks/pc_error_compare.py /path/to/pc_error --time --repeat 3

Figures: for each real frame of `tests.colour_pairs.FRAMES` under ``--shared`` (Longdress 1300, ricardo9 frame 1;
a missing one is skipped) and each processed copy (`tests.colour_pairs.processed_copies`: damaged, filled,
recoloured), both are written as PLY into ``--out`` and pc_error runs ``--color=1 --mseSpace=S`` (S = 1, BT.709
YCbCr, and 0, RGB); every colour figure it prints (c[k] MSE and PSNR, A->B, B->A, symmetric) is compared with
`metrics.colour.pc_error_colour` on the same clouds, and the worst relative difference is printed; the symmetric
PSNRs are printed as JSON (the golden values of tests/test_metrics_colour.py).

Time (``--time``): on the Longdress frame against its filled copy, ``--repeat`` rounds, each timing (wall clock,
and CPU seconds: user + system of the command and its threads) pc_error ``--color=1 --nbThreads=THREADS`` (the
frame has no normals, so pc_error computes D1 and colour: no D2), `dpcbench score --jobs THREADS` with the same
figures (D1, cpsnr_y/u/v), and `dpcbench score --jobs THREADS` with its default metrics (D1, D2 with estimated
normals, NSHD, Hausdorff, Chamfer, F-score, and colour PSNR Y/U/V), one after the other in this process's
niceness; the median of each is printed."""

from __future__ import annotations

import argparse
import json
import math
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

FIGURE = re.compile(r"^\s*(c\[\d\]),\s*(PSNR)?\s*([12F])\s*:\s*(\S+)\s*$")


def pc_error_figures(binary: str, a: Path, b: Path, space: int, threads: int) -> dict[str, float]:
    """The colour figures pc_error prints, under `pc_error_colour`'s names (``"c[0], F"``, ``"c[0],PSNRF"``)."""
    out = subprocess.run([binary, f"--fileA={a}", f"--fileB={b}", "--color=1", f"--mseSpace={space}",
                          f"--nbThreads={threads}"], check=True, capture_output=True, text=True).stdout
    figures = {}
    for line in out.splitlines():
        match = FIGURE.match(line)
        if match:
            channel, psnr, tag, value = match.groups()
            figures[f"{channel},PSNR{tag}" if psnr else f"{channel}, {tag}"] = float(value)
    if len(figures) != 18:
        raise SystemExit(f"pc_error printed {len(figures)} colour figures, expected 18:\n{out}")
    return figures


def relative(ours: float, theirs: float) -> float:
    if math.isinf(theirs) or math.isinf(ours):
        return 0.0 if ours == theirs else math.inf
    return abs(ours - theirs) / max(abs(theirs), 1e-300)


def write_pairs(shared: Path, out: Path) -> dict[str, dict[str, Path]]:
    """frame name -> {"truth": path, kind: path} of the frames present, written once into ``out``."""
    from dpcbench.bench.data.plyio import PointCloud, read_ply, write_ply
    from tests.colour_pairs import FRAMES, processed_copies

    written: dict[str, dict[str, Path]] = {}
    for name, rel in FRAMES.items():
        path = shared / "data" / rel
        if not path.is_file():
            print(f"{name}: {path} not present, skipped")
            continue
        cloud = read_ply(path)
        files = {"truth": path}
        for kind, (points, colours) in processed_copies(cloud.points, cloud.colors).items():
            files[kind] = out / f"{name}_{kind}.ply"
            if not files[kind].is_file():
                write_ply(files[kind], PointCloud(points, colours))
        written[name] = files
    return written


def compare(binary: str, pairs: dict[str, dict[str, Path]], threads: int) -> int:
    from dpcbench.bench.data.plyio import read_ply
    from dpcbench.metrics.colour import pc_error_colour

    golden: dict[str, dict[str, float]] = {}
    worst_all = 0.0
    print("| frame | copy | space | pc_error Y/R PSNR | ours | U/G | ours | V/B | ours | worst rel. diff (18 figures) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, files in pairs.items():
        truth = read_ply(files["truth"])
        for kind in (k for k in files if k != "truth"):
            copy = read_ply(files[kind])  # as written (float32 coordinates): what pc_error read
            for space in (1, 0):
                theirs = pc_error_figures(binary, files["truth"], files[kind], space, threads)
                ours = pc_error_colour(truth.points, copy.points, truth.colors, copy.colors, mse_space=space)
                worst = max(relative(ours[key], value) for key, value in theirs.items())
                worst_all = max(worst_all, worst)
                cells = " | ".join(f"{theirs[f'c[{k}],PSNRF']:.6f} | {ours[f'c[{k}],PSNRF']:.6f}" for k in range(3))
                print(f"| {name} | {kind} | {space} | {cells} | {worst:.2e} |", flush=True)
                golden[f"{name}/{kind}/space{space}"] = {f"c[{k}],PSNRF": theirs[f"c[{k}],PSNRF"] for k in range(3)}
    print("\npc_error's symmetric colour PSNRs (golden values):")
    print(json.dumps(golden, indent=1))
    print(f"\nworst relative difference over every figure: {worst_all:.2e}")
    return 0 if worst_all <= 1e-4 else 1


def timings(binary: str, files: dict[str, Path], threads: int, repeat: int) -> None:
    dpcbench = str(ROOT / ".venv" / "bin" / "dpcbench")
    truth, result = str(files["truth"]), str(files["filled"])
    commands = {
        f"pc_error --color=1 --nbThreads={threads} (D1, colour)": [
            binary, f"--fileA={truth}", f"--fileB={result}", "--color=1", f"--nbThreads={threads}"],
        f"dpcbench score --jobs {threads} (D1, cpsnr_y/u/v)": [
            dpcbench, "score", truth, result, "--jobs", str(threads), "--metric", "gpsnr_d1", "--metric", "cpsnr_y",
            "--metric", "cpsnr_u", "--metric", "cpsnr_v"],
        f"dpcbench score --jobs {threads} (default metrics + colour)": [dpcbench, "score", truth, result, "--jobs",
                                                                         str(threads)],
    }
    wall: dict[str, list[float]] = {label: [] for label in commands}
    cpu: dict[str, list[float]] = {label: [] for label in commands}
    for _ in range(repeat):
        for label, command in commands.items():
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            start = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True)
            wall[label].append(time.perf_counter() - start)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu[label].append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    print(f"\nLongdress 1300 against its filled copy, median of {repeat} rounds (each round runs all three):")
    print("| command | wall s | CPU s | wall, each round | CPU, each round |")
    print("|---|---|---|---|---|")
    for label in commands:
        print(f"| {label} | {statistics.median(wall[label]):.2f} | {statistics.median(cpu[label]):.2f} | "
              f"{', '.join(f'{v:.2f}' for v in wall[label])} | {', '.join(f'{v:.2f}' for v in cpu[label])} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("pc_error", nargs="?", help="path of the pc_error binary")
    parser.add_argument("--shared", default=str(ROOT.parent / "shared"), help="the shared folder (default ../shared)")
    parser.add_argument("--out", default=str(Path(tempfile.gettempdir()) / "dpcbench-pc-error-pairs"),
                        help="where the PLY copies are written (default: a folder in the temporary directory)")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--time", action="store_true", help="time dpcbench score against pc_error")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    if not args.pc_error or not Path(args.pc_error).is_file():
        print(f"skipped: no pc_error binary ({args.pc_error or 'none given'})")
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    pairs = write_pairs(Path(args.shared), out)
    if args.time:
        if "longdress" not in pairs:
            print("skipped: the Longdress frame is not present")
            return 0
        timings(args.pc_error, pairs["longdress"], args.threads, args.repeat)
        return 0
    return compare(args.pc_error, pairs, args.threads)


if __name__ == "__main__":
    raise SystemExit(main())
