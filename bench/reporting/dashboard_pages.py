"""The dashboard's drill-down pages: one HTML file per method configuration and one per run, in a
folder beside the main page (`dpcbench dashboard --out D.html` writes them to D_pages/), each
self-contained (inline CSS, inline PNG thumbnails, no script) and linked from the main page's
"Methods and runs" section and back to it.

- a method page (`method_page`): the configuration's summary rows at every code version of the
  history, one table per (sequence, holes): rows = code versions (newest first), columns = metric x
  scope (x peak), mean ± std; values carried over from an earlier version in grey; then its runs.
- a run page (`run_page`): the run's facts (data, damage, method, code version, times, machine,
  error), links to its run folder, manifest and log where the store recorded them and they exist
  on this machine, a thumbnail of frame 0 (damaged input beside the method's output, the points it
  added in red; `thumbnail_png`) when the run folder holds the frames, and the per-frame value of
  every metric (frames as rows; sequence-level values such as temporal consistency in a last row).

File names: `method_file` / `run_file` (a readable slug plus a short hash of the label or run id,
so that two labels never share a file).
"""

from __future__ import annotations

import base64
import html
import io
import os
from pathlib import Path

import numpy as np
import pandas as pd

from dpcbench.bench.experiment.records import run_env
from dpcbench.bench.reporting import dashboard as dash
from dpcbench.bench.reporting.dashboard import _runs_of, method_file, pages_section, run_file, runs_table  # noqa: F401
from dpcbench.bench.results import compare


def _e(value) -> str:
    return html.escape(str(value), quote=True)


def _document(title: str, body: str, back: str) -> str:
    """A page with the dashboard's inline style sheet, a header and a link back to the main page."""
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{_e(title)}</title>"
            f"<style>\n{dash.stylesheet()}</style></head><body><header><h1>{_e(title)}</h1>"
            f"<p><a class=\"back\" href=\"{_e(back)}\">← dashboard</a></p></header><main>{body}"
            "<footer>dpcbench · self-contained page</footer></main></body></html>\n")


def _column_title(metric: str, scope: str, peak: str) -> str:
    extra = f" · peak {peak}" if peak not in ("", "intrinsic") else ""
    return f"{_e(dash.metric_label(metric))}<br><span class='note'>{_e(scope)}{_e(extra)}</span>"


def _columns(rows: pd.DataFrame, metrics: list[str]) -> list[tuple[str, str, str]]:
    """(metric, scope, peak) columns present in ``rows``: scopes frame then holes, metrics in
    ``metrics`` order then time, the default peak first."""
    present = set(zip(rows["metric"], rows["scope"], rows["peak"]))
    scopes = [s for s in ("frame", "holes") if s in set(rows["scope"])] + sorted(set(rows["scope"]) - {"frame", "holes"})
    peaks = sorted(set(rows["peak"]), key=lambda p: (p not in ("", "intrinsic"), p))
    order = metrics + [m for m in ("time_s", "cpu_time_s", "peak_mem_mb") if m not in metrics]
    order += sorted(set(rows["metric"]) - set(order))
    return [(m, s, p) for s in scopes for m in order for p in peaks if (m, s, p) in present]


def method_page(page: dash.Page, label: str, back: str) -> str:
    """The page of one method configuration (see the module docstring)."""
    history = page.history
    table = history.table[history.table["label"] == label]
    ticks = dash.version_ticks(history)
    parts = [f'<section id="history"><h2>{_e(label)} over code versions</h2><p class="note">Mean ± std over '
             'frames (and seeds) of the newest run per cell at each code version, newest first; grey: carried over '
             'from an earlier version (not rerun at that one).</p>']
    for (sequence, holes, holes_params), rows in table.groupby(["sequence", "holes", "holes_params"], sort=True):
        columns = _columns(rows, page.quality_metrics)
        values = rows.set_index(["code_version", "metric", "scope", "peak"])
        head = "".join(f"<th>{_column_title(*c)}</th>" for c in columns)
        body = []
        for version in reversed(history.versions):
            cells = []
            for metric, scope, peak in columns:
                key = (version, metric, scope, peak)
                if key not in values.index:
                    cells.append('<td class="num">-</td>')
                    continue
                cell = values.loc[key]
                spread = f" ± {dash._fmt(cell['std'])}" if not pd.isna(cell["std"]) and cell["std"] else ""
                css = "num" + ("" if bool(cell["measured"]) else " carried")
                cells.append(f'<td class="{css}">{_e(dash._fmt(cell["mean"]))}{_e(spread)}</td>')
            if all(c == '<td class="num">-</td>' for c in cells):
                continue
            machine = history.version_machines.get(version, "")
            body.append(f'<tr data-version="{_e(version)}"><td title="{_e(version)}">{_e(ticks[version])}<br>'
                        f'<span class="note">{_e(history.version_dates.get(version, ""))}'
                        f'{_e(" · " + machine) if machine else ""}</span></td>{"".join(cells)}</tr>')
        parts.append(f"<h3>{_e(sequence)} · {_e(dash.holes_key(holes, holes_params))}</h3>"
                     f"<table class='history'><thead><tr><th>code version</th>{head}</tr></thead>"
                     f"<tbody>{''.join(body)}</tbody></table>")
    parts.append("</section>")
    runs = _runs_of(page.runs, label)
    if len(runs):
        parts.append('<section id="method-runs"><h2>Runs</h2>' + runs_table(runs, "") + "</section>")
    return _document(f"{label} · dpcbench", "".join(parts), back)


def run_links(run) -> list[tuple[str, str]]:
    """(text, file URI) of the run's folder, manifest and log, those that exist on this machine. The
    worker writes a run into ``<runs>/<inpaint key>/`` (the store's output_dir) and its log into
    ``<runs>/logs/<run id>.log``."""
    out: list[tuple[str, str]] = []
    folder = Path(str(run.output_dir)) if isinstance(run.output_dir, str) and run.output_dir else None
    if folder is None or not folder.is_dir():
        return out
    out.append(("run folder", folder.resolve().as_uri()))
    if (folder / "manifest.json").is_file():
        out.append(("manifest.json", (folder / "manifest.json").resolve().as_uri()))
    # a run id of a merged store carries a "<store index>:" prefix (commands.dashboard.load_stores)
    for run_id in dict.fromkeys([str(run.run_id), str(run.run_id).split(":", 1)[-1]]):
        log = folder.parent / "logs" / f"{run_id}.log"
        if log.is_file():
            out.append(("log", log.resolve().as_uri()))
            break
    return out


def thumbnail_png(folder: Path, frame: int = 0, height: int = 180, max_points: int = 200_000) -> bytes | None:
    """A small PNG of one frame of a run folder: the damaged input beside the method's output (grey,
    lighter = nearer, `render.rasterize`, no normals needed), the output's points that are not in the
    input (the fill) in red; None when the folder lacks that frame. Frames over ``max_points`` are
    drawn from a random subset of that many points (seed 0), so a thumbnail stays well under a second."""
    from scipy.spatial import cKDTree

    from dpcbench.bench.data.plyio import read_ply
    from dpcbench.bench.reporting import render

    damaged_path = folder / "damaged" / f"frame_{frame:04d}.ply"
    filled_path = folder / "inpainted" / f"frame_{frame:04d}.ply"
    if not damaged_path.is_file() or not filled_path.is_file():
        return None
    damaged = read_ply(damaged_path, colors=False).points
    filled = read_ply(filled_path, colors=False).points
    # a thumbnail needs no more points than it has pixels: large frames are subsampled (fixed seed)
    rng = np.random.default_rng(0)
    damaged, filled = (c if len(c) <= max_points else c[np.sort(rng.choice(len(c), max_points, replace=False))]
                       for c in (damaged, filled))
    rotation = render.view_rotation("front")
    both = render.rotate(np.vstack([damaged, filled]), rotation)
    lo, hi = both[:, :2].min(0), both[:, :2].max(0)
    pad = 0.03 * float(max(hi - lo)) + 1e-9
    lo, hi = lo - pad, hi + pad
    width = max(16, int(round(height * (hi[0] - lo[0]) / (hi[1] - lo[1]))))
    z_lo, z_hi = float(both[:, 2].min()), float(both[:, 2].max())

    def grey(points: np.ndarray) -> np.ndarray:
        z = render.rotate(points, rotation)[:, 2]
        level = 80 + 140 * (z - z_lo) / max(z_hi - z_lo, 1e-12)
        return np.repeat(level[:, None], 3, axis=1).astype(np.uint8)

    new = cKDTree(damaged).query(filled, k=1)[0] > 1e-9 if len(damaged) else np.ones(len(filled), bool)
    colours = grey(filled)
    colours[new] = render.HIGHLIGHT_COLOR
    gap = np.full((height, 6, 3), 255, np.uint8)
    image = np.hstack([render.rasterize(damaged, grey(damaged), rotation, (lo, hi), width, height, 1), gap,
                       render.rasterize(filled, colours, rotation, (lo, hi), width, height, 1)])
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    plt.imsave(buffer, image, format="png")
    return buffer.getvalue()


def _env_machine(run) -> str:
    return dash.machine_name(run_env(run.env))


def per_frame_table(rows: pd.DataFrame, metrics: list[str]) -> str:
    """Frames as rows, (metric, scope, peak) as columns; frame -1 (values of the whole sequence: the
    sequence's total time, temporal consistency) as a last row 'sequence'."""
    rows = rows.drop_duplicates(["frame", "metric", "scope", "peak"])
    columns = _columns(rows, metrics)
    values = rows.set_index(["frame", "metric", "scope", "peak"])["value"]
    head = "".join(f"<th>{_column_title(*c)}</th>" for c in columns)
    body = []
    frames = sorted(f for f in set(rows["frame"]) if f >= 0) + ([-1] if (rows["frame"] < 0).any() else [])
    for frame in frames:
        cells = "".join(f'<td class="num">{_e(dash._fmt(values[(frame,) + c]) if (frame,) + c in values.index else "-")}'
                        "</td>" for c in columns)
        body.append(f'<tr data-frame="{frame}"><td>{"sequence" if frame < 0 else frame}</td>{cells}</tr>')
    return (f"<table class='per-frame'><thead><tr><th>frame</th>{head}</tr></thead><tbody>{''.join(body)}</tbody>"
            "</table>")


def run_page(page: dash.Page, run, back: str, thumbnails: bool = True) -> str:
    """The page of one run (see the module docstring); ``run`` a row of the runs table."""
    label = dash.method_label(run.method, run.method_params or "{}")
    holes = dash.holes_key(run.holes, compare._canonical_json(run.holes_params or "{}"))
    machine = _env_machine(run)
    facts = [("method", f'<a href="{_e(method_file(label))}">{_e(label)}</a>'), ("sequence", _e(run.sequence)),
             ("holes", _e(holes)), ("seed", _e(run.seed)), ("method version", _e(run.method_version or "-")),
             ("code version", _e(run.code_version)), ("started / finished (UTC)",
                                                       _e(f"{run.created_at} / {run.finished_at}")),
             ("wall time", _e(dash.readable_seconds(run.wall_time_s))),
             ("CPU time", _e(dash.readable_seconds(run.cpu_time_s))),
             ("peak memory", _e("-" if pd.isna(run.peak_mem_mb) else f"{run.peak_mem_mb:.0f} MB")),
             ("machine", _e(machine or "not recorded")), ("status", _e(run.status)), ("run id", _e(run.run_id))]
    if run.status == "failed":
        facts.append(("error", f"<pre>{_e(run.error)}</pre>"))
    links = run_links(run)
    link_html = (" · ".join(f'<a href="{_e(uri)}">{_e(text)}</a>' for text, uri in links) if links else
                 "none on this machine (the store records no run folder, or it was removed or made elsewhere)")
    facts.append(("files", link_html))
    parts = ['<section id="facts"><h2>Run</h2><table class="facts"><tbody>'
             + "".join(f"<tr><th>{_e(k)}</th><td>{v}</td></tr>" for k, v in facts) + "</tbody></table></section>"]
    folder = Path(run.output_dir) if isinstance(run.output_dir, str) and run.output_dir else None
    if thumbnails:
        png = thumbnail_png(folder) if folder is not None and folder.is_dir() else None
        if png is not None:
            data = base64.b64encode(png).decode("ascii")
            parts.append('<section id="thumbnail"><h2>Frame 0</h2><p class="note">Left: the damaged input; right: '
                         "the method's output, the points it added in red (grey: lighter is nearer; front view)."
                         f'</p><img class="thumb" alt="frame 0: input and fill" src="data:image/png;base64,{data}">'
                         "</section>")
        else:
            parts.append('<section id="thumbnail"><h2>Frame 0</h2><p class="note">No thumbnail: the run folder with '
                         "its frames is not on this machine.</p></section>")
    rows = page.results[page.results["run_id"] == run.run_id]
    if len(rows):
        parts.append('<section id="per-frame"><h2>Per-frame values</h2><p class="note">Every metric the run '
                     'scored, per frame and scope; time in seconds per frame.</p>'
                     f'{per_frame_table(rows, page.quality_metrics)}</section>')
    return _document(f"run: {label} on {run.sequence} · dpcbench", "".join(parts), back)


def write_pages(folder: Path, page: dash.Page, main_name: str, thumbnails: bool = True) -> list[Path]:
    """Every method and run page into ``folder`` (atomic writes); returns their paths."""
    from dpcbench.bench.core.atomic import atomic_write_text

    folder.mkdir(parents=True, exist_ok=True)
    back = f"../{main_name}"
    written = []
    for label in sorted(set(page.history.table["label"])):
        written.append(atomic_write_text(folder / method_file(label), method_page(page, label, back)))
    for run in _runs_of(page.runs).itertuples(index=False):
        written.append(atomic_write_text(folder / run_file(run.run_id), run_page(page, run, back, thumbnails)))
    return written


def write_dashboard(out: str | os.PathLike, results: pd.DataFrame, *, runs: pd.DataFrame | None = None,
                    benchmarks: pd.DataFrame | None = None, baseline: tuple[pd.DataFrame, dict] | None = None,
                    tolerances: dict[str, float] | None = None, machines: dict[str, str] | None = None,
                    pages: bool = False, thumbnails: bool = True, **kwargs) -> list[Path]:
    """Render and write the page atomically; with ``pages``, a page per method configuration and
    per run (this module) into the folder '<out stem>_pages' beside it. Returns the
    paths written, the main page first."""
    from dpcbench.bench.core.atomic import atomic_write_text

    out = Path(out)
    prepared = dash.prepare_page(results, runs, benchmarks, baseline, tolerances, machines)
    pages_dir = f"{out.stem}_pages" if pages and prepared.history.versions else ""
    written = [atomic_write_text(out, dash.render_dashboard(results, prepared=prepared, pages_dir=pages_dir, **kwargs))]
    if pages_dir:
        written += write_pages(out.parent / pages_dir, prepared, out.name, thumbnails)
    return written
