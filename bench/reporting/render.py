"""Figures of point clouds: frames side by side (rows x columns), orthographic views rasterized with
numpy (a z-buffer over splatted points, so 1M points take about a second; matplotlib's scatter would
take minutes), shaded by colour or by normals, with an optional magnified zoom box and highlighted
points; and the paper-style comparison figure (`render_zoom_grid`: configurations as columns,
frames as rows, every hole magnified in a row of its own, with a key).

Projection: the cloud is rotated by ``view_rotation(view)`` (camera looks along -z after rotation;
screen x = rotated x, screen y = rotated y, nearer = larger rotated z). Every panel of a figure uses
the same scale and the same bounds, so motion and sizes compare across panels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dpcbench.bench.core.atomic import atomic_path
from dpcbench.bench.core.errors import UserError
from dpcbench.metrics.neighbours import estimate_normals, median_neighbour_distance

#: neighbours of the normals estimated for shading a cloud that carries none
SHADING_NORMAL_NEIGHBOURS = 16

VIEWS = {"front": (0.0, 0.0), "back": (180.0, 0.0), "left": (-90.0, 0.0), "right": (90.0, 0.0),
         "top": (0.0, 90.0)}
HIGHLIGHT_COLOR = (230, 20, 20)
SHADINGS = ("auto", "color", "normal", "shaded")


def view_rotation(view) -> np.ndarray:
    """3x3 rotation for a view name in VIEWS or an (azimuth, elevation) pair in degrees:
    R = R_x(elevation) @ R_y(azimuth). "front" looks at the +z face, "left" at the +x face, "top" at +y."""
    if isinstance(view, str):
        if view not in VIEWS:
            raise UserError(f"unknown view {view!r}; use one of {', '.join(VIEWS)} or (azimuth, elevation)")
        azimuth, elevation = VIEWS[view]
    else:
        azimuth, elevation = (float(v) for v in view)
    a, e = np.radians(azimuth), np.radians(elevation)
    ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    rx = np.array([[1, 0, 0], [0, np.cos(e), -np.sin(e)], [0, np.sin(e), np.cos(e)]])
    return rx @ ry


def rotate(points: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """points @ rotation.T, (N, 3), written as three broadcast products: BLAS matmul of a tall
    (N, 3) array is slower here, and much slower when other processes load the cores."""
    return points[:, :1] * rotation[:, 0] + points[:, 1:2] * rotation[:, 1] + points[:, 2:3] * rotation[:, 2]


def lambert(normals: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Lambert intensity (N,) of unoriented normals: 0.2 + 0.8 |n' . l|, n' = R n (view space),
    l = unit (-0.3, 0.4, 1) (light from the viewer, a little up-left)."""
    light = np.array([-0.3, 0.4, 1.0])
    light /= np.linalg.norm(light)
    return 0.2 + 0.8 * np.abs(rotate(normals, rotation) @ light)


def shade_normals(normals: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Grey-blue shading (N, 3) uint8: ``lambert`` intensity times RGB (200, 205, 215)."""
    base = np.array([200.0, 205.0, 215.0])
    return np.clip(lambert(normals, rotation)[:, None] * base, 0, 255).astype(np.uint8)


def panel_colours(points: np.ndarray, colors, normals, shading: str, rotation: np.ndarray) -> np.ndarray:
    """The (N, 3) uint8 colours a panel is drawn with (see render_clouds' ``shading``)."""
    if shading == "color" and colors is None:
        raise UserError("shading='color' but the cloud has no colours; use shading='auto' or 'normal'")
    use_normals = shading in ("normal", "shaded") or colors is None
    if use_normals and normals is None:
        normals = estimate_normals(points, SHADING_NORMAL_NEIGHBOURS) if len(points) >= 3 else None
    if colors is None or shading == "normal":
        if normals is None:  # fewer than 3 points: no normal to estimate
            return np.full((len(points), 3), 128, np.uint8)
        return shade_normals(normals, rotation)
    colors = np.asarray(colors)
    if shading == "shaded" and normals is not None:
        return np.clip(colors * lambert(normals, rotation)[:, None], 0, 255).astype(np.uint8)
    return np.array(colors, dtype=np.uint8, copy=True)


def _disk_offsets(radius: int) -> np.ndarray:
    r = int(radius)
    dy, dx = np.mgrid[-r:r + 1, -r:r + 1]
    keep = dx ** 2 + dy ** 2 <= r * r + r  # a round splat; radius 1 is a 3x3 square, 2 drops the corners
    return np.stack([dy[keep], dx[keep]], 1)


def rasterize(points: np.ndarray, colors: np.ndarray, rotation: np.ndarray, bounds: tuple[np.ndarray, np.ndarray],
              width: int, height: int, radius: int = 1, background=(255, 255, 255)) -> np.ndarray:
    """(height, width, 3) uint8 image of ``points`` (N, 3) with ``colors`` (N, 3) uint8.

    ``bounds`` = (lo, hi) screen-space (2,) corners of the area shown (view-rotated x, y). Each point
    covers a disk of ``radius`` pixels; at every pixel the nearest point (largest view z) wins: a
    z-buffer written with ``np.minimum.at`` on depth ranks, so the result does not depend on the order
    of the points.
    """
    image = np.empty((height, width, 3), dtype=np.uint8)
    image[:] = background
    if len(points) == 0:
        return image
    view = rotate(points, rotation)
    lo, hi = bounds
    scale = min((width - 1) / max(hi[0] - lo[0], 1e-12), (height - 1) / max(hi[1] - lo[1], 1e-12))
    col = np.rint((view[:, 0] - lo[0]) * scale).astype(np.int64)
    row = np.rint((hi[1] - view[:, 1]) * scale).astype(np.int64)
    rank = np.empty(len(view), dtype=np.int64)
    order = np.argsort(-view[:, 2], kind="stable")  # nearest first, ties by index: deterministic
    rank[order] = np.arange(len(view))
    zbuf = np.full(height * width, len(view), dtype=np.int64)
    for dy, dx in _disk_offsets(radius):
        r, c = row + dy, col + dx
        ok = (r >= 0) & (r < height) & (c >= 0) & (c < width)
        np.minimum.at(zbuf, r[ok] * width + c[ok], rank[ok])
    hit = zbuf < len(view)
    image.reshape(-1, 3)[hit] = np.asarray(colors)[order[zbuf[hit]]]
    return image


def _as_grid(items, nested: bool, n_rows: int, n_cols: int, what: str) -> list[list]:
    """Per-panel options (None, or one entry per panel nested like the clouds) as rows x cols."""
    if items is None:
        return [[None] * n_cols for _ in range(n_rows)]
    rows = [list(row) for row in items] if nested else [list(items)]
    if len(rows) != n_rows or any(len(row) != n_cols for row in rows):
        raise UserError(f"{what}: give one entry per panel ({n_rows} row(s) x {n_cols} column(s)), "
                         "nested like the clouds")
    return rows


def _unpack(cloud):
    """(points, colours or None, normals or None) of an (N, 3) array or a PointCloud-like object."""
    if hasattr(cloud, "points"):
        points = np.asarray(cloud.points, dtype=np.float64)
        return points, getattr(cloud, "colors", None), getattr(cloud, "normals", None)
    return np.asarray(cloud, dtype=np.float64), None, None


def zoom_box(zoom) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) 3D axis-aligned box from 6 numbers (x0, y0, z0, x1, y1, z1), a (2, 3) array, or a
    HoleRegion-like object: centre +- radius (ball) or centre +- |R| half_extents (rotated box)."""
    if hasattr(zoom, "center"):
        centre = np.asarray(zoom.center, dtype=np.float64)
        if getattr(zoom, "radius", None) is not None:
            half = np.full(3, float(zoom.radius))
        else:
            rot = np.asarray(getattr(zoom, "rotation", None) if getattr(zoom, "rotation", None) is not None
                             else np.eye(3), dtype=np.float64)
            half = np.abs(rot) @ np.asarray(zoom.half_extents, dtype=np.float64)
        return centre - half, centre + half
    box = np.asarray(zoom, dtype=np.float64).reshape(-1)
    if box.shape != (6,) or not np.isfinite(box).all():
        raise UserError(f"zoom box must be 6 numbers x0,y0,z0,x1,y1,z1, got {zoom!r}")
    lo, hi = np.minimum(box[:3], box[3:]), np.maximum(box[:3], box[3:])
    if np.any(hi - lo <= 0):
        raise UserError(f"zoom box {box.tolist()} has zero size along an axis")
    return lo, hi


def point_spacing(points: np.ndarray, sample: int = 50_000) -> float:
    """Median nearest-neighbour spacing of ``points`` (N, 3); 0 for fewer than 2 points.

    On large clouds the distances are those of ``sample`` probe points to their nearest neighbour in the
    whole cloud (`metrics.neighbours.median_neighbour_distance`). The spacing of a random subset scaled by
    the thinning would not do: a random subset's nearest neighbours lie about half as far apart as a
    grid's at the same density, so a voxelized frame's spacing came out 0.48 voxel and its splats left a
    grid of gaps in close zooms.
    """
    if len(points) < 2:
        return 0.0
    return median_neighbour_distance(np.asarray(points, dtype=np.float64), sample=sample)


def splat_size(spacing: float, pixels_per_unit: float, *, cover: float = 0.5, limit: int = 6,
               minimum: int = 0) -> int:
    """Splat radius (pixels) that closes the gaps between neighbouring points ``spacing`` apart at
    ``pixels_per_unit``: ``cover`` x the spacing in pixels, rounded up, within ``minimum``..``limit``.
    0.5 closes the gaps along a grid's rows, 0.7 also its diagonal ones (sqrt(2)/2 spacing). A figure
    computes it once, from its reference cloud, and draws every panel of one scale with it: a radius
    per panel makes a sparse output (fewer points, larger splats) look magnified."""
    if not np.isfinite(spacing) or spacing <= 0:
        return int(min(limit, max(minimum, 2)))  # a single point: any visible dot
    return int(min(limit, max(minimum, np.ceil(cover * spacing * pixels_per_unit))))


def _checked_panels(grid, colors_g, highlight_g, shading: str, rotation: np.ndarray) -> list[list[tuple]]:
    """render_clouds' panels as rows of (points, colours (N, 3) uint8), highlights painted; refuses
    bad shapes and non-finite points with the panel's position."""
    panels = []
    for r, cloud_row in enumerate(grid):
        row = []
        for c, cloud in enumerate(cloud_row):
            pts, own_colors, normals = _unpack(cloud)
            if pts.ndim != 2 or pts.shape[1] != 3:
                raise UserError(f"panel ({r}, {c}): points must be an (N, 3) array, got shape {pts.shape}")
            if not np.isfinite(pts).all():
                raise UserError(f"panel ({r}, {c}): the cloud has NaN or infinite coordinates")
            col = colors_g[r][c] if colors_g[r][c] is not None else own_colors
            if col is not None and np.shape(col) != pts.shape:
                raise UserError(f"panel ({r}, {c}): colours have shape {np.shape(col)}, points {pts.shape}")
            col = panel_colours(pts, col, normals, shading, rotation)
            mask = highlight_g[r][c]
            if mask is not None:
                mask = np.asarray(mask, dtype=bool)
                if mask.shape != (len(pts),):
                    raise UserError(f"panel ({r}, {c}): highlight mask has shape {mask.shape}, expected ({len(pts)},)")
                col[mask] = HIGHLIGHT_COLOR
            row.append((pts, col))
        panels.append(row)
    return panels


def screen_bounds(clouds, rotation: np.ndarray, margin: float = 0.03) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) screen-space (view-rotated x, y) corners around every non-empty cloud of ``clouds``
    ((N, 3) arrays), grown by ``margin`` x the larger side: the one frame every panel of a figure shares."""
    screen = [rotate(p, rotation)[:, :2] for p in clouds if len(p)]
    if not screen:
        raise UserError("nothing to render: every cloud is empty")
    lo = np.min([s.min(0) for s in screen], axis=0)
    hi = np.max([s.max(0) for s in screen], axis=0)
    pad = margin * max(hi - lo) + 1e-9
    return lo - pad, hi + pad


def _box_on_screen(box, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Screen (lo, hi) of a 3D box's 8 corners projected."""
    corners = rotate(np.array([[x, y, z] for x in (box[0][0], box[1][0]) for y in (box[0][1], box[1][1])
                               for z in (box[0][2], box[1][2])]), rotation)
    return corners[:, :2].min(0), corners[:, :2].max(0)


def _draw_box_zoom(ax, zoom_ax, pts, col, box, rotation, frame, zoom_height: int, point_size, spacing: float):
    """render_clouds' zoom: the box's outline on the full view ``ax`` (``frame`` = (lo, hi, scale))
    and the points inside the box, magnified, on ``zoom_ax``."""
    from matplotlib.patches import Rectangle

    lo, hi, scale = frame
    blo, bhi = _box_on_screen(box, rotation)
    ax.add_patch(Rectangle(((blo[0] - lo[0]) * scale, (hi[1] - bhi[1]) * scale), (bhi[0] - blo[0]) * scale,
                           (bhi[1] - blo[1]) * scale, fill=False, edgecolor="orange", linewidth=1.2))
    inside = np.all((pts >= box[0]) & (pts <= box[1]), axis=1)
    zw = max(16, int(round(zoom_height * (bhi[0] - blo[0]) / max(bhi[1] - blo[1], 1e-12))))
    zscale = min((zw - 1) / max(bhi[0] - blo[0], 1e-12), (zoom_height - 1) / max(bhi[1] - blo[1], 1e-12))
    radius = point_size if point_size is not None else splat_size(spacing, zscale, cover=0.7)
    zoom_ax.imshow(rasterize(pts[inside], col[inside], rotation, (blo, bhi), zw, zoom_height, radius),
                   interpolation="nearest")
    zoom_ax.set_xticks([])
    zoom_ax.set_yticks([])
    for spine in zoom_ax.spines.values():
        spine.set_edgecolor("orange")
    zoom_ax.set_title("zoom", fontsize=8, color="darkorange")


def render_clouds(clouds, out_png, titles=None, colors=None, zoom=None, highlight=None, view="front",
                  point_size: int | None = None, panel_height: int = 480, shading: str = "auto",
                  zoom_height: int | None = None, dpi: int = 100, suptitle: str | None = None) -> Path:
    """Draw point clouds side by side and save a PNG; returns its path.

    clouds:     a list of clouds (one row) or a list of rows (rows x columns, e.g. rows = methods,
                columns = frames). A cloud is an (N, 3) array or a PointCloud (its colours/normals used).
    titles:     one string per panel (same nesting), or None.
    colors:     per-panel (N, 3) uint8 colours overriding the cloud's own, or None.
    zoom:       a 3D box (x0, y0, z0, x1, y1, z1) or a HoleRegion-like object (center + radius or
                half_extents): its outline is drawn on every panel and the magnified crop (the points
                inside the box) in a row under each row of panels.
    highlight:  per-panel boolean masks (N,) of points to paint red (e.g. the filled points), or None.
    view:       a name in VIEWS or (azimuth, elevation) degrees.
    point_size: splat radius in pixels; None = `splat_size` of the first non-empty panel's point
                spacing, the same for every panel (and one for every zoom).
    shading:    "auto" (colours when present, else normals), "color", "normal" (grey Lambert shading
                of the normals), or "shaded" (colours times the Lambert intensity, to see the geometry
                of coloured clouds); normals are estimated with open3d when the cloud has none.
    """
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["text.parse_math"] = False  # labels are user text, never TeX
    import matplotlib.pyplot as plt

    from dpcbench.bench.core.progress import progress_bar

    if shading not in SHADINGS:
        raise UserError(f"shading must be one of {', '.join(SHADINGS)}, got {shading!r}")
    clouds = list(clouds)
    if not clouds:
        raise UserError("nothing to render: the list of clouds is empty")
    nested = isinstance(clouds[0], (list, tuple))
    grid = [list(row) for row in clouds] if nested else [clouds]
    n_rows, n_cols = len(grid), max(len(r) for r in grid)
    if any(len(r) != n_cols for r in grid):
        raise UserError("every row of clouds must have the same number of panels")
    titles_g = _as_grid(titles, nested, n_rows, n_cols, "titles")
    rotation = view_rotation(view)
    panels = _checked_panels(grid, _as_grid(colors, nested, n_rows, n_cols, "colors"),
                             _as_grid(highlight, nested, n_rows, n_cols, "highlight"), shading, rotation)

    lo, hi = screen_bounds([p for row in panels for p, _ in row], rotation)
    height = int(panel_height)
    width = max(16, int(round(height * (hi[0] - lo[0]) / (hi[1] - lo[1]))))
    scale = min((width - 1) / (hi[0] - lo[0]), (height - 1) / (hi[1] - lo[1]))
    spacing = point_spacing(next(p for row in panels for p, _ in row if len(p)))
    radius = point_size if point_size is not None else splat_size(spacing, scale)

    box = zoom_box(zoom) if zoom is not None else None
    zh = int(zoom_height or height // 2)
    per_row = 2 if box is not None else 1
    row_heights = [h for _ in range(n_rows) for h in ([height, zh] if box is not None else [height])]
    fig_h = sum(row_heights) / dpi + 0.35 * n_rows * per_row + (0.4 if suptitle else 0.0)
    fig, axes = plt.subplots(n_rows * per_row, n_cols, figsize=(n_cols * width / dpi + 0.2 * n_cols, fig_h),
                             squeeze=False, gridspec_kw={"height_ratios": row_heights})

    cells = [(r, c) for r in range(n_rows) for c in range(n_cols)]
    large = sum(len(panels[r][c][0]) for r, c in cells) > 2_000_000  # about 2 s of rasterizing
    for r, c in progress_bar(cells, desc="rendering", unit="panel", quiet=None if large else True):
        pts, col = panels[r][c]
        ax = axes[r * per_row][c]
        ax.imshow(rasterize(pts, col, rotation, (lo, hi), width, height, radius), interpolation="nearest")
        ax.set_axis_off()
        if titles_g[r][c]:
            ax.set_title(str(titles_g[r][c]), fontsize=9)
        if box is not None:
            _draw_box_zoom(ax, axes[r * 2 + 1][c], pts, col, box, rotation, (lo, hi, scale), zh, point_size, spacing)
    if suptitle:
        fig.suptitle(suptitle)
    # tight_layout ignores the suptitle: keep the top 0.4 inch (reserved in fig_h) for it
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - (0.4 / fig_h if suptitle else 0.0)))
    out = Path(out_png)
    with atomic_path(out, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=dpi, facecolor="white")
    plt.close(fig)
    return out


def tint_highlight(colors: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``colors`` (N, 3) uint8 with the points of ``mask`` tinted red, keeping their shading (the shape
    of a fill stays readable, unlike a flat red): grey level g = mean(c) / 255 becomes
    (90 + 165 g, 30 g, 30 g), from dark red to HIGHLIGHT_COLOR-like red."""
    out = np.asarray(colors).copy()
    if mask is not None and np.any(mask):
        g = out[mask].astype(np.float64).mean(axis=1, keepdims=True) / 255.0
        tinted = np.array([90.0, 0.0, 0.0]) + g * np.array([165.0, 30.0, 30.0])
        out[mask] = np.clip(tinted, 0, 255).astype(np.uint8)
    return out


#: the colour of the zoom areas' outlines and of the zoom panels' frames
ZOOM_COLOUR = "darkorange"
#: the smallest text of a comparison figure at its print width (points)
FIGURE_TEXT_PT = 7.0


@dataclass(frozen=True)
class Zoom:
    """One magnified area of a comparison figure: the 3D ``centre`` of a hole, seen from ``view``
    (a VIEWS name or (azimuth, elevation); None: the figure's own view)."""

    centre: np.ndarray
    view: object = None


@dataclass(frozen=True)
class ComparisonFigure:
    """What `render_zoom_grid` wrote and drew with: the PNG and the PDF beside it, the one splat
    radius (pixels at ``dpi``) of every body panel and the one of every zoom panel, the size in
    inches, the column labels in order and, top to bottom, the (frame row, zoom index) of each zoom row."""

    png: Path
    pdf: Path
    body_splat: int
    zoom_splat: int
    size_in: tuple[float, float]
    dpi: int
    columns: list[str]
    zoom_rows: list[tuple[int, int]] = field(default_factory=list)


@dataclass(frozen=True)
class _Layout:
    """Inches of a comparison figure: label margin, column pitch, panel width, body and zoom row
    heights, header (title and column labels) and key heights, gap; ``rows``: (kind, frame, zoom) top to bottom."""

    label_in: float
    pitch_in: float
    panel_in: float
    body_in: float
    head_in: float
    key_in: float
    gap_in: float
    rows: list[tuple[str, int, int]]
    label_lines: list[str]

    @property
    def height_in(self) -> float:
        rows = sum((self.body_in if kind == "body" else self.panel_in) + self.gap_in for kind, _, _ in self.rows)
        return self.head_in + rows + self.key_in


def _wrap_label(text: str, chars: int) -> str:
    import textwrap

    # at spaces, or after a hyphen ("temporal-" / "graph"); a word is never cut elsewhere
    return "\n".join(textwrap.wrap(str(text), max(4, chars), break_long_words=False)) or str(text)


def _layout(n_cols: int, zooms: list[list], aspect: float, column_labels: list[str], width_in: float,
            title: str | None) -> _Layout:
    """The inch layout of `render_zoom_grid`: columns share ``width_in`` less the row-label margin;
    column labels wrap to the column's width at `FIGURE_TEXT_PT` (about 0.6 em a character: DejaVu Sans)."""
    label_in, gap_in = 0.36, 0.03
    pitch_in = (width_in - label_in) / n_cols
    panel_in = pitch_in - gap_in
    chars = int(pitch_in * 72.0 / (0.6 * FIGURE_TEXT_PT))
    lines = [_wrap_label(label, chars) for label in column_labels]
    line_in = 1.2 * FIGURE_TEXT_PT / 72.0
    head_in = (0.25 if title else 0.0) + max(text.count("\n") + 1 for text in lines) * line_in + 0.05
    rows = []
    for f, frame_zooms in enumerate(zooms):
        rows.append(("body", f, -1))
        rows.extend(("zoom", f, k) for k in range(len(frame_zooms)))
    return _Layout(label_in, pitch_in, panel_in, panel_in * aspect, head_in, 0.3, gap_in, rows, lines)


def _comparison_panels(grid, highlight, shading: str) -> list[list[tuple]]:
    """Rows of (points, own colours or None, normals or None, highlight mask or None); normals
    estimated once here when the shading needs them (every zoom re-shades from its own view)."""
    highlight_g = _as_grid(highlight, True, len(grid), len(grid[0]), "highlight")
    panels = []
    for r, cloud_row in enumerate(grid):
        row = []
        for c, cloud in enumerate(cloud_row):
            pts, own_colors, normals = _unpack(cloud)
            if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.isfinite(pts).all():
                raise UserError(f"panel ({r}, {c}): points must be a non-empty finite (N, 3) array, got {pts.shape}")
            if normals is None and len(pts) >= 3 and (shading in ("normal", "shaded") or own_colors is None):
                normals = estimate_normals(pts, SHADING_NORMAL_NEIGHBOURS)
            mask = highlight_g[r][c]
            if mask is not None:
                mask = np.asarray(mask, dtype=bool)
                if mask.shape != (len(pts),):
                    raise UserError(f"panel ({r}, {c}): highlight mask has shape {mask.shape}, expected ({len(pts)},)")
            row.append((pts, own_colors, normals, mask))
        panels.append(row)
    return panels


def _panel_image(panel, shading: str, rotation, bounds, width: int, height: int, radius: int,
                 depth_window: tuple[float, float] | None = None) -> np.ndarray:
    """One panel rasterized from ``rotation``: shaded from that view, highlight tinted; with
    ``depth_window`` (centre depth, half depth) only the points within it and inside ``bounds``."""
    pts, own_colors, normals, mask = panel
    if depth_window is not None:
        v = rotate(pts, rotation)
        lo, hi = bounds
        keep = (np.all((v[:, :2] >= lo) & (v[:, :2] <= hi), axis=1)
                & (np.abs(v[:, 2] - depth_window[0]) <= depth_window[1]))
        pts = pts[keep]
        own_colors = None if own_colors is None else np.asarray(own_colors)[keep]
        normals = None if normals is None else np.asarray(normals)[keep]
        mask = None if mask is None else mask[keep]
    col = panel_colours(pts, own_colors, normals, shading, rotation)
    col = tint_highlight(col, mask) if mask is not None else col
    return rasterize(pts, col, rotation, bounds, width, height, radius)


def _add_image_axes(fig, x_in: float, top_in: float, w_in: float, h_in: float, image):
    """An axes at (``x_in``, ``top_in`` from the top) of ``w_in`` x ``h_in`` inches showing ``image``."""
    W, H = fig.get_size_inches()
    ax = fig.add_axes((x_in / W, 1.0 - (top_in + h_in) / H, w_in / W, h_in / H))
    ax.imshow(image, interpolation="nearest", aspect="auto")
    ax.set_xticks([])
    ax.set_yticks([])
    return ax


def _draw_labels_and_key(fig, layout: _Layout, row_tops: list[float], row_labels: list[str],
                         column_colours: list, title: str | None) -> None:
    """Title, column labels (in the columns' colours), row labels (vertical, at the left) and the key
    (the red tint and the orange zoom area), all at `FIGURE_TEXT_PT` or more."""
    from matplotlib.patches import Patch

    W, H = fig.get_size_inches()
    if title:
        fig.text(0.5, 1.0 - 0.12 / H, title, ha="center", va="center", fontsize=FIGURE_TEXT_PT + 1)
    for c, text in enumerate(layout.label_lines):
        x = layout.label_in + c * layout.pitch_in + layout.panel_in / 2
        fig.text(x / W, 1.0 - (layout.head_in - 0.03) / H, text, ha="center", va="bottom", fontsize=FIGURE_TEXT_PT,
                 color=column_colours[c] or "black", linespacing=1.0)
    for (kind, f, k), top in zip(layout.rows, row_tops):
        h = layout.body_in if kind == "body" else layout.panel_in
        holes = sum(1 for kind_, f_, _ in layout.rows if kind_ == "zoom" and f_ == f)
        text = (row_labels[f] + ("" if holes else "\n(no hole)")) if kind == "body" else f"{row_labels[f]}\nhole {k + 1}"
        fig.text(0.5 * layout.label_in / W, 1.0 - (top + h / 2) / H, text, rotation=90, ha="center", va="center",
                 fontsize=FIGURE_TEXT_PT, linespacing=1.0, color="black" if kind == "body" else ZOOM_COLOUR)
    red = tint_highlight(np.full((1, 3), 200, np.uint8), np.ones(1, bool))[0] / 255.0
    handles = [Patch(facecolor=red, edgecolor="none", label="points inside a hole region (the fill)"),
               Patch(fill=False, edgecolor=ZOOM_COLOUR, label="zoom area k, magnified in the row 'hole k'")]
    fig.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=2, frameon=False,
               fontsize=FIGURE_TEXT_PT, handlelength=1.4)


def _zoom_outline(ax, zoom: Zoom, rotation, frame, half: float, number: int) -> None:
    """The orange square of ``zoom`` on a body panel (``frame`` = (lo, hi, pixels per unit)) and its number."""
    from matplotlib.patches import Rectangle

    lo, hi, scale = frame
    c = rotate(np.asarray(zoom.centre, float).reshape(1, 3), rotation)[0]
    x0, y0, side = (c[0] - half - lo[0]) * scale, (hi[1] - c[1] - half) * scale, 2 * half * scale
    ax.add_patch(Rectangle((x0, y0), side, side, fill=False, edgecolor=ZOOM_COLOUR, linewidth=0.8))
    ax.text(x0 + side, y0, str(number), color=ZOOM_COLOUR, fontsize=FIGURE_TEXT_PT, ha="left", va="bottom")


def _save_png_and_pdf(fig, out_png, dpi: int) -> tuple[Path, Path]:
    """``fig`` as PNG at ``dpi`` (exactly its size in inches x dpi: no tight bounding box) and PDF beside it."""
    out = Path(out_png)
    pdf = out.with_suffix(".pdf")
    with atomic_path(out, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=dpi, facecolor="white")
    with atomic_path(pdf, suffix=".pdf") as tmp:
        fig.savefig(tmp, dpi=dpi, facecolor="white")
    return out, pdf


def render_zoom_grid(grid, out_png, *, column_labels: list[str], row_labels: list[str], zooms: list[list],
                     zoom_half: float | None = None, highlight=None, view="front", shading: str = "normal",
                     column_colours: list | None = None, reference: tuple[int, int] = (0, 0),
                     width_in: float = 7.2, dpi: int = 300, title: str | None = None) -> ComparisonFigure:
    """A paper-style comparison figure (Fig. 3/4): one column per configuration (e.g. ground truth,
    damaged input, each method); per frame (a row of ``grid``) a row of whole bodies with every zoom
    area outlined in orange and numbered, then one row per zoom area: that area magnified in every
    column, seen from the zoom's own view. Written as PNG (``dpi``) and PDF, ``width_in`` wide.

    grid:           rows (frames) of clouds ((N, 3) arrays or PointClouds), every row as long.
    column_labels:  one per column, on top (in ``column_colours``' colours, None = black);
                    row_labels: one per frame, written vertically at the left.
    zooms:          per frame, a list of `Zoom` (or 3D centres); every hole gets its own zoom row.
    zoom_half:      half the side of every zoom square, in coordinate units (default: 12 x the
                    reference cloud's point spacing): one magnification for the whole figure.
    highlight:      per panel (nested like ``grid``) boolean masks of points to tint red, or None.
    reference:      (row, column) of the cloud whose point spacing sets the splat sizes (the ground
                    truth): one radius for every body panel and one for every zoom (`splat_size`).
    A zoom shows the points whose screen position lies in its square and whose depth is within
    2 ``zoom_half`` of its centre's: surfaces far in front of or behind the hole (another limb, the
    back of the body) do not cover it.
    """
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["text.parse_math"] = False  # labels are user text, never TeX
    import matplotlib.pyplot as plt

    rows = [list(r) for r in grid]
    n_rows, n_cols = len(rows), len(rows[0]) if rows else 0
    if n_rows == 0 or n_cols == 0 or any(len(r) != n_cols for r in rows):
        raise UserError("grid: give rows of clouds, every row with the same (non-zero) number of panels")
    if len(row_labels) != n_rows or len(column_labels) != n_cols or len(zooms) != n_rows:
        raise UserError(f"give {n_rows} row labels, {n_cols} column labels and {n_rows} lists of zooms "
                        f"(got {len(row_labels)}, {len(column_labels)}, {len(zooms)})")
    if column_colours is not None and len(column_colours) != n_cols:
        raise UserError(f"column_colours: give one colour (or None) per column ({n_cols}), got {len(column_colours)}")
    if shading not in SHADINGS:
        raise UserError(f"shading must be one of {', '.join(SHADINGS)}, got {shading!r}")
    zooms = [[z if isinstance(z, Zoom) else Zoom(np.asarray(z, float)) for z in frame] for frame in zooms]
    panels = _comparison_panels(rows, highlight, shading)
    rotation = view_rotation(view)
    lo, hi = screen_bounds([p[0] for row in panels for p in row], rotation)
    layout = _layout(n_cols, zooms, (hi[1] - lo[1]) / (hi[0] - lo[0]), column_labels, width_in, title)
    pw, bh = max(16, int(round(layout.panel_in * dpi))), max(16, int(round(layout.body_in * dpi)))
    scale = min((pw - 1) / (hi[0] - lo[0]), (bh - 1) / (hi[1] - lo[1]))
    spacing = point_spacing(panels[reference[0]][reference[1]][0])
    zoom_half = float(zoom_half if zoom_half is not None else 12.0 * (spacing or 1.0))
    if not zoom_half > 0:
        raise UserError(f"zoom_half must be positive, got {zoom_half}")
    body_splat = splat_size(spacing, scale)
    zoom_splat = splat_size(spacing, (pw - 1) / (2 * zoom_half), cover=0.7, limit=max(2, pw // 12), minimum=1)

    fig = plt.figure(figsize=(width_in, layout.height_in))
    top, tops = layout.head_in, []
    for kind, f, k in layout.rows:
        tops.append(top)
        for c in range(n_cols):
            x = layout.label_in + c * layout.pitch_in
            if kind == "body":
                image = _panel_image(panels[f][c], shading, rotation, (lo, hi), pw, bh, body_splat)
                ax = _add_image_axes(fig, x, top, layout.panel_in, layout.body_in, image)
                ax.set_axis_off()
                for j, zoom in enumerate(zooms[f]):
                    _zoom_outline(ax, zoom, rotation, (lo, hi, scale), zoom_half, j + 1)
                continue
            zoom = zooms[f][k]
            zoom_rotation = rotation if zoom.view is None else view_rotation(zoom.view)
            centre = rotate(np.asarray(zoom.centre, float).reshape(1, 3), zoom_rotation)[0]
            bounds = (centre[:2] - zoom_half, centre[:2] + zoom_half)
            image = _panel_image(panels[f][c], shading, zoom_rotation, bounds, pw, pw, zoom_splat,
                                 depth_window=(centre[2], 2 * zoom_half))
            ax = _add_image_axes(fig, x, top, layout.panel_in, layout.panel_in, image)
            for spine in ax.spines.values():
                spine.set_edgecolor(ZOOM_COLOUR)
        top += (layout.body_in if kind == "body" else layout.panel_in) + layout.gap_in
    _draw_labels_and_key(fig, layout, tops, row_labels, list(column_colours or [None] * n_cols), title)
    png, pdf = _save_png_and_pdf(fig, out_png, dpi)
    plt.close(fig)
    return ComparisonFigure(png, pdf, body_splat, zoom_splat, (float(width_in), layout.height_in), int(dpi),
                            list(column_labels), [(f, k) for kind, f, k in layout.rows if kind == "zoom"])
