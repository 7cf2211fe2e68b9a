"""A campaign of bad inputs against every `dpcbench` command, as a user runs them.

    python tests/campaign_errors.py [--subprocess-only]

Builds a workspace in a temporary folder (tiny sequence, holes.json, corrupt files, a damaged
store), then runs (1) the generated family of `tests/test_errors.py` in-process and (2) hand-written
cases as real `dpcbench` subprocesses. A case is handled when the command exits 2 with
exactly one line on stderr, ``dpcbench COMMAND: error: ...``, no traceback, and no file outside its
--out changed. Prints the cases not handled and the count tried / handled.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def load_test_module():
    spec = importlib.util.spec_from_file_location("test_errors", REPO / "tests" / "test_errors.py")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(REPO))
    spec.loader.exec_module(module)
    return module


def workspace(t, root: Path) -> Path:
    import numpy as np

    from dpcbench.bench.data.plyio import PointCloud, write_ply
    from dpcbench.holes.regions import HoleRegion, regions_to_json

    ws = root / "ws"
    frames = [t.sphere(800, f, shift=0.5 * f) for f in range(3)]
    for f, pts in enumerate(frames):
        write_ply(ws / "seq" / f"s_{f:04d}.ply", PointCloud(pts, np.full((len(pts), 3), 120, dtype=np.uint8)))
    (ws / "holes.json").write_text(json.dumps(regions_to_json([[HoleRegion.ball(p[0], 6.0)] for p in frames])))
    return ws


def subprocess_cases(ws: Path, bad: dict) -> list[tuple[list[str], str | None]]:
    far = json.loads((ws / "holes.json").read_text())
    for entry in far["frames"]:
        entry["regions"] = [{"shape": "ball", "center": [9000.0, 0.0, 0.0], "radius": 2.0}]
    (ws / "far.json").write_text(json.dumps(far))
    shifted = json.loads((ws / "holes.json").read_text())
    shifted["frames"][1]["frame"] = 9
    (ws / "shifted.json").write_text(json.dumps(shifted))
    cfg = ("[experiment]\nname = \"e\"\n[[sequences]]\nname = \"{name}\"\nparams = {{ size = \"tiny\" }}\nframes = 2\n"
           "[[holes]]\ngenerator = \"region\"\nparams = {{ cube_size = {cube} }}\n[[methods]]\nname = \"none\"\n")
    (ws / "abc.toml").write_text(cfg.format(name="human", cube='"abc"'))
    (ws / "typo.toml").write_text(cfg.format(name="humna", cube="20"))
    (ws / "mine.json").write_text("{}")
    a_file, seq, out = bad["a_file"], str(ws / "seq"), str(ws / "out")
    # issue 51: a link planted in --out, a damage output (ground truth), hostile values and files
    (ws / "linked").mkdir(exist_ok=True)
    if not (ws / "linked" / "masks.npz").is_symlink():
        (ws / "linked" / "masks.npz").symlink_to(ws / "seq" / "s_0001.ply")
    (ws / "truth").mkdir(exist_ok=True)
    (ws / "truth" / "holes.json").write_text(json.dumps({"format": "dpcbench-holes", "version": 1,
                                                         "generator": "region", "frames": []}))
    inf_radius = json.loads((ws / "holes.json").read_text())
    inf_radius["frames"][0]["regions"][0]["radius"] = float("inf")
    (ws / "inf.json").write_text(json.dumps(inf_radius))
    (ws / "objs").mkdir(exist_ok=True)
    (ws / "objs" / "m_0000.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n")
    (ws / "seeds.toml").write_text(cfg.format(name="human", cube="20").replace('generator = "region"',
                                                                               'generator = "region"\nseeds = [-1]'))
    truth, linked = str(ws / "truth"), str(ws / "linked")
    c = [
        (["detect-holes", seq, "--out", seq + "/s_0001.ply"], None),
        (["detect-holes", seq, "--out", seq + "/s_0001.ply", "--overwrite"], None),
        (["detect-holes", seq, "--out", str(ws / "mine.json")], None),
        (["detect-holes", seq, "--out", a_file + "/h.json"], None),
        (["detect-holes", seq, "--param", "k=abc", "--out", out + ".json"], out + ".json"),
        (["detect-holes", seq, "--param", "k=2", "--out", out + ".json"], out + ".json"),
        (["damage", seq, "--holes", "region", "--param", "cube_size=abc", "--out", out], out),
        (["damage", seq, "--holes", "region", "--param", "shape=blob", "--out", out], out),
        (["damage", seq, "--holes", "occlusion", "--param", "per_ring=abc", "--out", out], out),
        (["damage", seq, "--holes", "dropout", "--param", "fraction=2", "--out", out], out),
        (["damage", seq, "--holes", "region", "--out", a_file], None),
        (["damage", seq, "--holes", "region", "--out", a_file + "/d"], None),
        (["damage", seq, "--holes", "region", "--out", seq], None),
        (["inpaint", seq, "--method", "none", "--regions", bad["list.json"], "--out", out], out),
        (["inpaint", seq, "--method", "none", "--regions", str(ws / "shifted.json"), "--out", out], out),
        (["inpaint", seq, "--method", "temporal-copy", "--regions", str(ws / "far.json"), "--out", out], out),
        (["inpaint", seq, "--method", "temporal-graph", "--regions", str(ws / "far.json"), "--out", out], out),
        (["inpaint", seq, "--method", "temporal-graph", "--param", "cube_size=abc", "--out", out], out),
        (["inpaint", seq, "--method", "lozes-pde", "--param", "p=3", "--regions", str(ws / "holes.json"),
          "--out", out], out),
        (["inpaint", seq, "--method", "none", "--regions", str(ws / "holes.json"), "--out", a_file], None),
        (["score", seq, seq, "--region", bad["list.json"]], None),
        (["score", seq, seq, "--region", str(ws / "far.json")], None),
        (["score", seq, seq, "--region", str(ws / "holes.json"), "--region-margin", "-100"], None),
        (["score", seq, seq, "--region", str(ws / "shifted.json")], None),
        (["score", seq, bad["seq_nan"]], None),
        (["score", bad["seq_short_ascii"], seq], None),
        (["render", seq, "--holes", bad["list.json"], "--out", out + ".png"], out + ".png"),
        (["render", seq, "--zoom", "1,2,3", "--out", out + ".png"], out + ".png"),
        (["render", seq, "--shading", "color", "--out", a_file + "/x.png"], None),
        (["info", bad["short_ascii.ply"]], None),
        (["info", bad["truncated.ply"]], None),
        (["info", "human", "--param", "bit_depth=abc"], None),
        (["run", str(ws / "abc.toml"), "--dry-run"], None),
        (["run", str(ws / "typo.toml"), "--dry-run"], None),
        (["run", "toml", "--dry-run"], None),
        (["run", "paper-quick", "--dry-run", "--store", bad["damaged_store"]], None),
        (["run", "paper-quick", "--dry-run", "--store", a_file + "/r.sqlite"], None),
        (["report", bad["damaged_store"], "--out", out], out),
        (["report", bad["text.sqlite"], "--out", out], out),
        (["compare", bad["summary.csv"], bad["damaged_store"]], None),
        (["dashboard", "--store", bad["damaged_store"], "--out", out + ".html"], out + ".html"),
        (["generate", "human", "--param", "size=huge", "--out", out], out),
        (["generate", "human", "--out", a_file], None),
        (["reproduce-paper", "--quick", "--frames", "1", "--out", out], out),
        (["damage", seq, "--holes", "region", "--out", linked, "--overwrite"], linked),
        (["detect-holes", seq, "--out", truth + "/holes.json"], None),
        (["generate", "human", "--param", "size=tiny", "--frames", "1", "--out", truth], None),
        (["compare", "--save-current", truth + "/holes.json"], None),
        (["inpaint", seq, "--method", "temporal-copy", "--regions", str(ws / "inf.json"), "--out", out], out),
        (["inpaint", seq, "--frames", "2,1,0", "--method", "none", "--regions", str(ws / "holes.json"), "--out", out],
         out),
        (["damage", "human", "--frames", "99999999", "--holes", "region", "--out", out], out),
        (["damage", seq, "--holes", "region", "--seed", "-1", "--out", out], out),
        (["score", seq, seq, "--peak", "1e200"], None),
        (["inpaint", seq, "--method", "meshlab", "--param", "poisson_depth=2.5", "--out", out], out),
        (["run", str(ws / "seeds.toml"), "--dry-run"], None),
        (["run", "paper-quick", "--scheduler", "tcp://host:99999"], None),
        (["generate", str(ws / "objs"), "--out", out], out),
    ]
    return c


def main() -> int:
    t = load_test_module()
    with tempfile.TemporaryDirectory(prefix="dpcbench-campaign-") as tmp:
        root = Path(tmp)
        os.environ.update(DPCBENCH_QUIET="1", DPCBENCH_CACHE=str(root / "_cache"),
                          DPCBENCH_STORE=str(root / "_store" / "results.sqlite"))
        ws = workspace(t, root)
        os.chdir(ws)
        bad = {k: str(v) for k, v in t.bad_files(ws).items()}
        restore = t.good_inputs(ws)
        tried = handled = 0
        problems: list[str] = []
        if "--subprocess-only" not in sys.argv:
            import contextlib
            import io

            cases = t.bad_input_family(ws)
            from dpcbench.bench.cli import main as cli_main

            for argv, out in cases:
                restore()
                before = t.tree_hashes(ws, skip=out)
                err = io.StringIO()
                try:
                    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                        code = cli_main(argv)
                except BaseException as exc:  # any exception at all: a traceback is what the campaign hunts for
                    code, err = None, io.StringIO(f"raised {type(exc).__name__}: {exc}")
                tried += 1
                lines = err.getvalue().strip().splitlines()
                ok = (code == 2 and len(lines) == 1 and lines[0].startswith(f"dpcbench {argv[0]}: error:")
                      and t.tree_hashes(ws, skip=out) == before)
                handled += ok
                if not ok:
                    problems.append(f"in-process {argv}: exit {code}: {err.getvalue()!r}")
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        for argv, out in subprocess_cases(ws, bad):
            restore()
            before = t.tree_hashes(ws, skip=Path(out) if out else None)
            proc = subprocess.run([sys.executable, "-m", "dpcbench.bench.cli", *argv], capture_output=True, text=True, env=env)
            tried += 1
            lines = proc.stderr.strip().splitlines()
            ok = (proc.returncode == 2 and len(lines) == 1 and lines[0].startswith(f"dpcbench {argv[0]}: error:")
                  and "Traceback" not in proc.stderr
                  and t.tree_hashes(ws, skip=Path(out) if out else None) == before)
            handled += ok
            print(f"{'ok ' if ok else 'BAD'} {' '.join(argv)}\n    -> {proc.returncode}: {proc.stderr.strip()[:300]}")
            if not ok:
                problems.append(f"subprocess {argv}: exit {proc.returncode}: {proc.stderr!r}")
        for p in problems:
            print("NOT HANDLED:", p)
        print(f"campaign: {tried} bad inputs tried, {handled} handled")
        return 0 if handled == tried else 1


if __name__ == "__main__":
    sys.exit(main())
