"""Provenance and run folders: where a result came from, and the folder of frames it was scored on.

- `git_commit` / `environment`: the one probe of the code version and the environment, recorded
  with every run (``env`` in the store) and in every summary's header (`summary_environment`).
- A **run folder** ``RUNS_DIR/<inpaint_key>/`` holds what one (data, holes, method) produced:

      damaged/frame_0000.ply ...    the damaged input frames (float32 PLY, colours when the data has them)
      inpainted/frame_0000.ply ...  the method's output frames (with colours when the damaged frames have them:
                                    `methods._colour`'s fill "auto", as `dpcbench inpaint` gives by default)
      holes.json                    the hole regions (`holes.regions.regions_to_json`) and removed fractions
      detected.json                 the detected regions, when the protocol detects them
      manifest.json                 the run's identity and timings (see `bench.execution.worker.produce_frames`)

  `write_run_folder` writes it atomically (`bench.core.atomic.atomic_folder`); `read_run_folder` reads it
  back. A folder with ``manifest.json`` is complete: the worker reuses it instead of re-inpainting.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
from pathlib import Path

import numpy as np

#: packages whose versions every run records (those not installed are left out)
RECORDED_PACKAGES = ("dpcbench", "numpy", "scipy", "open3d", "pymeshlab", "pandas", "matplotlib", "plyfile",
                     "dask", "distributed")
#: packages a summary's header names (with "not installed" when absent)
SUMMARY_PACKAGES = ("numpy", "scipy", "open3d", "pymeshlab", "pandas")


def git_commit(repo: str | os.PathLike | None = None) -> str:
    """The checked-out commit of ``repo`` (default: this checkout), with "+dirty" when tracked files
    are modified, or "unknown" (no git, not a checkout)."""
    cwd = Path(repo) if repo else Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True,
                                timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                               capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return commit + ("+dirty" if dirty else "")


def package_versions(names=RECORDED_PACKAGES) -> dict[str, str | None]:
    """name -> installed version, or None when the package is not installed."""
    from importlib import metadata

    versions: dict[str, str | None] = {}
    for name in names:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def environment() -> dict:
    """Package versions, Python, git commit and machine of this process (a run's ``env``)."""
    return {
        "packages": {k: v for k, v in package_versions().items() if v is not None},
        "python": platform.python_version(),
        "git_commit": git_commit(),
        "machine": {"node": platform.node(), "system": platform.system(), "release": platform.release(),
                    "arch": platform.machine(), "cpus": os.cpu_count()},
        "isa": _isa(),
    }


def _isa() -> str:
    from dpcbench.bench.core.isa import describe

    return describe()


def summary_environment() -> dict:
    """The environment as a summary's flat header block: python, a version (or "not installed") per
    `SUMMARY_PACKAGES`, machine ("Linux x86_64, 8 cpus") and processor."""
    info = {"python": platform.python_version()}
    info.update({k: v or "not installed" for k, v in package_versions(SUMMARY_PACKAGES).items()})
    info["machine"] = f"{platform.system()} {platform.machine()}, {os.cpu_count()} cpus"
    info["processor"] = platform.processor() or platform.machine()
    return info


# -- how D2 got its reference normals --------------------------------------------------------------
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


# -- run folders -----------------------------------------------------------------------------------
def _json_default(value):
    """numpy values inside region extras (e.g. rim points) as plain JSON."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def write_run_folder(run_dir: Path, *, damaged: list[np.ndarray], damaged_colors: list | None,
                     inpainted: list[np.ndarray], holes: dict, detected: dict | None, manifest: dict,
                     inpainted_colors: list | None = None) -> None:
    """Write a run folder (layout in the module doc) atomically, replacing one of that name.

    damaged / inpainted: the (N_f, 3) frames; damaged_colors / inpainted_colors: their (N_f, 3) uint8 colours
    or None;
    holes / detected: `holes.regions.regions_to_json` documents; manifest: the run's facts (JSON).
    """
    from dpcbench.bench.core.atomic import atomic_folder
    from dpcbench.bench.data.plyio import PointCloud, write_ply

    # double coordinates when the input needs them (float32 cannot hold the damaged frames exactly:
    # georeferenced or float64 data); float32, as always, for data that float32 holds
    precision = None if all(_float32_exact(frame) for frame in damaged) else "float64"
    with atomic_folder(run_dir) as tmp:
        for i, (frame, result) in enumerate(zip(damaged, inpainted)):
            colors = None if damaged_colors is None else damaged_colors[i]
            write_ply(tmp / "damaged" / f"frame_{i:04d}.ply", PointCloud(frame, colors, precision=precision))
            result_colors = None if inpainted_colors is None else inpainted_colors[i]
            write_ply(tmp / "inpainted" / f"frame_{i:04d}.ply", PointCloud(result, result_colors, precision=precision))
        (tmp / "holes.json").write_text(json.dumps(holes, indent=1, default=_json_default))
        if detected is not None:
            (tmp / "detected.json").write_text(json.dumps(detected, indent=1, default=_json_default))
        # the checksum of every file written, so that a folder changed afterwards is never trusted
        manifest = {**manifest, "sha256": folder_checksums(tmp)}
        (tmp / "manifest.json").write_text(json.dumps(manifest, indent=1, default=str))


def _float32_exact(points: np.ndarray) -> bool:
    """Whether every coordinate of ``points`` survives a float32 round trip unchanged."""
    points = np.asarray(points)
    if points.dtype == np.float32 or points.dtype.kind in "iu" and points.dtype.itemsize <= 2:
        return True
    return bool(np.array_equal(points.astype(np.float32).astype(points.dtype), points))


def folder_checksums(folder: Path) -> dict[str, str]:
    """{relative path: sha256 hex} of every file under ``folder`` but ``manifest.json``."""
    import hashlib

    out = {}
    for path in sorted(p for p in Path(folder).rglob("*") if p.is_file() and p.name != "manifest.json"):
        digest = hashlib.sha256()
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                digest.update(block)
        out[path.relative_to(folder).as_posix()] = digest.hexdigest()
    return out


def verify_run_folder(run_dir: Path, manifest: dict) -> None:
    """Refuse (UserError) a run folder whose files differ from the checksums its manifest recorded
    (a file changed, missing or added since the run wrote it) or whose manifest names another
    folder (``inpaint_key``). A manifest without checksums (an older dpcbench) is not checked here."""
    from dpcbench.bench.core.errors import UserError

    key = manifest.get("inpaint_key")
    if key is not None and key != Path(run_dir).name:
        raise UserError(f"{run_dir}: its manifest belongs to run folder {key}, not to this one; the folder was copied "
                        "or renamed: remove it (or rerun with --force)")
    recorded = manifest.get("sha256")
    if recorded is None:
        return
    found = folder_checksums(run_dir)
    changed = sorted(name for name in set(recorded) | set(found) if recorded.get(name) != found.get(name))
    if changed:
        shown = ", ".join(changed[:3]) + (f" and {len(changed) - 3} more" if len(changed) > 3 else "")
        raise UserError(f"{run_dir}: {len(changed)} file(s) differ from what the run wrote ({shown}: changed, missing "
                        "or added); its results cannot be trusted: remove the folder (or rerun with --force)")


def read_run_folder(run_dir: Path) -> dict:
    """The damaged and inpainted frames ((N,3) arrays), the inpainted frames' colours (None unless every frame
    has them), regions and manifest of a run folder, after `verify_run_folder`."""
    from dpcbench.bench.data.plyio import read_ply
    from dpcbench.bench.data.sequences import natural_key
    from dpcbench.holes.regions import regions_from_json

    run_dir = Path(run_dir)
    manifest = json.loads((run_dir / "manifest.json").read_text())
    verify_run_folder(run_dir, manifest)

    def clouds(sub):
        files = sorted((run_dir / sub).glob("*.ply"), key=lambda p: natural_key(p.name))
        return [read_ply(f) for f in files]

    inpainted = clouds("inpainted")
    colours = [c.colors for c in inpainted]
    detected = run_dir / "detected.json"
    return {"damaged": [c.points for c in clouds("damaged")], "inpainted": [c.points for c in inpainted],
            "inpainted_colors": colours if inpainted and all(c is not None for c in colours) else None,
            "regions": regions_from_json(run_dir / "holes.json"),
            "detected": regions_from_json(detected) if detected.is_file() else None,
            "manifest": manifest}


def is_complete_run_folder(run_dir: Path) -> bool:
    """True when ``run_dir`` was written to the end (its manifest is the last file written)."""
    return (Path(run_dir) / "manifest.json").is_file()


def clean_stale_temp(runs_dir: Path) -> int:
    """Remove temporary run folders (``.tmp-*``) whose writer process is gone (left by killed runs)."""
    from dpcbench.bench.core.atomic import remove_stale_folders

    return remove_stale_folders(runs_dir)
