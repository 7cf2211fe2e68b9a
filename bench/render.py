"""Figures of point clouds: frames side by side (rows x columns), orthographic views rasterized with
numpy (a z-buffer over splatted points, so 1M points take about a second; matplotlib's scatter would
take minutes), shaded by colour or by normals, with an optional magnified zoom box and highlighted
points.

Projection: the cloud is rotated by ``view_rotation(view)`` (camera looks along -z after rotation;
screen x = rotated x, screen y = rotated y, nearer = larger rotated z). Every panel of a figure uses
the same scale and the same bounds, so motion and sizes compare across panels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dpcbench.bench.atomic import atomic_path
from dpcbench.bench.errors import UserError
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


def _auto_radius(points: np.ndarray, scale: float, sample: int = 50_000) -> int:
    """Splat radius (pixels) that closes the gaps between neighbouring points: half the median
    nearest-neighbour spacing in pixels, rounded up, within 0..6.

    On large clouds the spacing is measured on a fixed random subset of ``sample`` points (seed 0)
    and divided by sqrt(N / sample): on a surface, thinning by k spreads points by sqrt(k). That
    avoids a KD-tree over a million points for a number that only needs to be roughly right.
    """
    from dpcbench.metrics.neighbours import probe

    n = len(points)
    if n < 2:
        return 2
    subset = probe(points, sample, seed=0)
    # the spacing of the subset itself (its own tree), rescaled to the whole cloud
    spacing = median_neighbour_distance(subset, sample=None) / np.sqrt(n / len(subset)) * scale
    return int(min(6, max(0, np.ceil(0.5 * spacing))))


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
    point_size: splat radius in pixels; None = from the point spacing.
    shading:    "auto" (colours when present, else normals), "color", "normal" (grey Lambert shading
                of the normals), or "shaded" (colours times the Lambert intensity, to see the geometry
                of coloured clouds); normals are estimated with open3d when the cloud has none.
    """
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["text.parse_math"] = False  # labels are user text, never TeX
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from dpcbench.bench.progress import progress_bar

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
    colors_g = _as_grid(colors, nested, n_rows, n_cols, "colors")
    highlight_g = _as_grid(highlight, nested, n_rows, n_cols, "highlight")
    rotation = view_rotation(view)

    panels = []
    for r in range(n_rows):
        row = []
        for c in range(n_cols):
            pts, own_colors, normals = _unpack(grid[r][c])
            if pts.ndim != 2 or pts.shape[1] != 3:
                raise UserError(f"panel ({r}, {c}): points must be an (N, 3) array, got shape {pts.shape}")
            if not np.isfinite(pts).all():
                raise UserError(f"panel ({r}, {c}): the cloud has NaN or infinite coordinates")
            col = colors_g[r][c] if colors_g[r][c] is not None else own_colors
            if col is not None and np.shape(col) != pts.shape:
                raise UserError(f"panel ({r}, {c}): colours have shape {np.shape(col)}, points {pts.shape}")
            col = panel_colours(pts, col, normals, shading, rotation)
            if col.shape != pts.shape:
                raise UserError(f"panel ({r}, {c}): colours have shape {col.shape}, points {pts.shape}")
            mask = highlight_g[r][c]
            if mask is not None:
                mask = np.asarray(mask, dtype=bool)
                if mask.shape != (len(pts),):
                    raise UserError(f"panel ({r}, {c}): highlight mask has shape {mask.shape}, expected ({len(pts)},)")
                col[mask] = HIGHLIGHT_COLOR
            row.append((pts, col))
        panels.append(row)

    # common screen bounds over all panels, with a 3% margin
    screen = [rotate(p, rotation) for row in panels for p, _ in row if len(p)]
    if not screen:
        raise UserError("nothing to render: every cloud is empty")
    lo = np.min([s[:, :2].min(0) for s in screen], axis=0)
    hi = np.max([s[:, :2].max(0) for s in screen], axis=0)
    pad = 0.03 * max(hi - lo) + 1e-9
    lo, hi = lo - pad, hi + pad
    height = int(panel_height)
    width = max(16, int(round(height * (hi[0] - lo[0]) / (hi[1] - lo[1]))))
    scale = min((width - 1) / (hi[0] - lo[0]), (height - 1) / (hi[1] - lo[1]))

    box = zoom_box(zoom) if zoom is not None else None
    zh = int(zoom_height or height // 2)
    rows_out = n_rows * (2 if box is not None else 1)
    row_heights = []
    for _ in range(n_rows):
        row_heights.append(height)
        if box is not None:
            row_heights.append(zh)
    fig_w = n_cols * width / dpi
    fig_h = sum(row_heights) / dpi + 0.35 * rows_out + (0.4 if suptitle else 0.0)
    fig, axes = plt.subplots(rows_out, n_cols, figsize=(fig_w + 0.2 * n_cols, fig_h), squeeze=False,
                             gridspec_kw={"height_ratios": row_heights})

    cells = [(r, c) for r in range(n_rows) for c in range(n_cols)]
    large = sum(len(panels[r][c][0]) for r, c in cells) > 2_000_000  # about 2 s of rasterizing
    for r, c in progress_bar(cells, desc="rendering", unit="panel", quiet=None if large else True):
        pts, col = panels[r][c]
        radius = point_size if point_size is not None else _auto_radius(pts, scale)
        ax = axes[r * (2 if box is not None else 1)][c]
        ax.imshow(rasterize(pts, col, rotation, (lo, hi), width, height, radius), interpolation="nearest")
        ax.set_axis_off()
        if titles_g[r][c]:
            ax.set_title(str(titles_g[r][c]), fontsize=9)
        if box is None:
            continue
        # the zoom box's screen rectangle (its 8 corners projected) on the full view
        corners = rotate(np.array([[x, y, z] for x in (box[0][0], box[1][0]) for y in (box[0][1], box[1][1])
                                   for z in (box[0][2], box[1][2])]), rotation)
        blo, bhi = corners[:, :2].min(0), corners[:, :2].max(0)
        ax.add_patch(Rectangle(((blo[0] - lo[0]) * scale, (hi[1] - bhi[1]) * scale), (bhi[0] - blo[0]) * scale,
                               (bhi[1] - blo[1]) * scale, fill=False, edgecolor="orange", linewidth=1.2))
        inside = np.all((pts >= box[0]) & (pts <= box[1]), axis=1)
        zoom_ax = axes[r * 2 + 1][c]
        zw = max(16, int(round(zh * (bhi[0] - blo[0]) / max(bhi[1] - blo[1], 1e-12))))
        zscale = min((zw - 1) / max(bhi[0] - blo[0], 1e-12), (zh - 1) / max(bhi[1] - blo[1], 1e-12))
        zradius = point_size
        if zradius is None:
            zradius = _auto_radius(pts[inside], zscale) if inside.sum() > 1 else 2
        zoom_ax.imshow(rasterize(pts[inside], col[inside], rotation, (blo, bhi), zw, zh, zradius),
                       interpolation="nearest")
        zoom_ax.set_xticks([])
        zoom_ax.set_yticks([])
        for spine in zoom_ax.spines.values():
            spine.set_edgecolor("orange")
        zoom_ax.set_title("zoom", fontsize=8, color="darkorange")
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


def _zoom_radius(points: np.ndarray, scale: float, limit: int) -> int:
    """Splat radius (pixels) for a magnified crop: 0.7 x the point spacing in pixels, rounded up
    (so that disks also close the diagonal gaps of a voxel grid, sqrt(2)/2 spacing), within
    1..``limit`` (the zoom magnifies far beyond `_auto_radius`'s cap of 6)."""
    if len(points) < 2:
        return max(1, min(limit, 3))
    return int(min(limit, max(1, np.ceil(0.7 * median_neighbour_distance(points, sample=None) * scale))))


def render_zoom_grid(grid, out_png, *, row_labels: list[str], column_labels: list[str], zooms: list,
                     zoom_half: float | None = None, highlight=None, view="front", shading: str = "normal",
                     panel_height: int = 260, dpi: int = 100, title: str | None = None) -> Path:
    """A paper-style subjective figure: rows (e.g. ground truth, damaged, each method) x columns
    (frames); each cell shows the whole cloud with the zoom area outlined in orange and, beside it,
    that area magnified (a square panel as tall as the cloud's).

    grid:          rows of clouds ((N, 3) arrays or PointClouds), all rows of the same length.
    row_labels:    one per row, written vertically at the left; column_labels: one per column, on top.
    zooms:         per column, the 3D centre (3,) of its zoom area, or None (that column's zoom
                   panel says "no hole"); every column is magnified equally.
    zoom_half:     half the side of the zoom square, in coordinate units (default: 12 x the median
                   point spacing of the first row's first cloud).
    highlight:     per panel (nested like ``grid``) boolean masks of points to tint red, or None.
    The zoom shows the points whose screen position lies in the square and whose depth is within
    2 ``zoom_half`` of the centre's: surfaces far in front of or behind the hole (another limb, the
    back of the body) do not cover it. Every panel uses the same view and scale; every zoom the same
    magnification. Each cell is ``panel_height`` pixels tall and (1 + the clouds' width / height) x
    ``panel_height`` wide; 260 (the default) prints a 3-frame figure at about 380 dpi a column wide.
    """
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["text.parse_math"] = False  # labels are user text, never TeX
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    rows = [list(r) for r in grid]
    n_rows, n_cols = len(rows), len(rows[0]) if rows else 0
    if n_rows == 0 or n_cols == 0 or any(len(r) != n_cols for r in rows):
        raise ValueError("grid: give rows of clouds, every row with the same (non-zero) number of panels")
    if len(row_labels) != n_rows or len(column_labels) != n_cols or len(zooms) != n_cols:
        raise ValueError(f"give {n_rows} row labels, {n_cols} column labels and {n_cols} zoom centres "
                         f"(got {len(row_labels)}, {len(column_labels)}, {len(zooms)})")
    if shading not in SHADINGS:
        raise ValueError(f"shading must be one of {', '.join(SHADINGS)}, got {shading!r}")
    highlight_g = _as_grid(highlight, True, n_rows, n_cols, "highlight")
    rotation = view_rotation(view)
    panels = []
    for r in range(n_rows):
        row = []
        for c in range(n_cols):
            pts, own_colors, normals = _unpack(rows[r][c])
            if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.isfinite(pts).all():
                raise ValueError(f"panel ({r}, {c}): points must be a non-empty finite (N, 3) array, got {pts.shape}")
            col = panel_colours(pts, own_colors, normals, shading, rotation)
            mask = highlight_g[r][c]
            if mask is not None:
                mask = np.asarray(mask, dtype=bool)
                if mask.shape != (len(pts),):
                    raise ValueError(f"panel ({r}, {c}): highlight mask has shape {mask.shape}, expected ({len(pts)},)")
                col = tint_highlight(col, mask)
            row.append((pts, col, rotate(pts, rotation)))
        panels.append(row)

    lo = np.min([v[:, :2].min(0) for row in panels for _, _, v in row], axis=0)
    hi = np.max([v[:, :2].max(0) for row in panels for _, _, v in row], axis=0)
    pad = 0.03 * max(hi - lo) + 1e-9
    lo, hi = lo - pad, hi + pad
    H = int(panel_height)
    W = max(16, int(round(H * (hi[0] - lo[0]) / (hi[1] - lo[1]))))
    scale = min((W - 1) / (hi[0] - lo[0]), (H - 1) / (hi[1] - lo[1]))
    if zoom_half is None:
        first = panels[0][0][0]
        spacing = median_neighbour_distance(first, sample=None) if len(first) > 1 else 1.0
        zoom_half = 12.0 * spacing
    zoom_half = float(zoom_half)
    if not zoom_half > 0:
        raise ValueError(f"zoom_half must be positive, got {zoom_half}")
    Z = H  # square zoom panels as tall as the clouds
    zscale = (Z - 1) / (2 * zoom_half)

    # canvas layout in pixels: row labels | (cloud, zoom) per column | ...; column labels on top
    label_w = int(0.3 * H)  # room for a two-line row label
    head_h = int(0.2 * H) + (int(0.2 * H) if title else 0)
    gap_in, gap_out, gap_row = max(2, H // 60), max(6, H // 12), max(4, H // 25)
    cell_w = W + gap_in + Z
    width = label_w + n_cols * cell_w + (n_cols - 1) * gap_out + gap_in
    height = head_h + n_rows * H + (n_rows - 1) * gap_row + gap_in
    canvas = np.full((height, width, 3), 255, dtype=np.uint8)
    frames = []
    zoom_frames: list[tuple[int, int, bool | None]] = []  # None: a panel without a hole
    for r in range(n_rows):
        y = head_h + r * (H + gap_row)
        for c in range(n_cols):
            x = label_w + c * (cell_w + gap_out)
            pts, col, v = panels[r][c]
            canvas[y:y + H, x:x + W] = rasterize(pts, col, rotation, (lo, hi), W, H, _auto_radius(pts, scale))
            zx = x + W + gap_in
            centre = zooms[c]
            if centre is None:
                canvas[y:y + Z, zx:zx + Z] = 238
                zoom_frames.append((zx, y, None))
                continue
            cz = rotate(np.asarray(centre, dtype=np.float64).reshape(1, 3), rotation)[0]
            zlo, zhi = cz[:2] - zoom_half, cz[:2] + zoom_half
            inside = ((v[:, 0] >= zlo[0]) & (v[:, 0] <= zhi[0]) & (v[:, 1] >= zlo[1]) & (v[:, 1] <= zhi[1])
                      & (np.abs(v[:, 2] - cz[2]) <= 2 * zoom_half))
            crop = pts[inside]
            radius = _zoom_radius(crop, zscale, max(2, Z // 12))
            canvas[y:y + Z, zx:zx + Z] = rasterize(crop, col[inside], rotation, (zlo, zhi), Z, Z, radius)
            frames.append((x + (zlo[0] - lo[0]) * scale, y + (hi[1] - zhi[1]) * scale, 2 * zoom_half * scale))
            zoom_frames.append((zx, y, True))

    fig = plt.figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(canvas, interpolation="nearest")
    ax.set_xlim(-0.5, width - 0.5)
    ax.set_ylim(height - 0.5, -0.5)
    ax.set_axis_off()
    # text about an eighth of a panel tall: about 7 pt when a 3-frame figure is printed a column wide
    font = 0.125 * H * 72.0 / dpi
    line = max(1.0, H / 130.0)
    for x0, y0, side in frames:
        ax.add_patch(Rectangle((x0, y0), side, side, fill=False, edgecolor="darkorange", linewidth=line))
    for zx, y, has in zoom_frames:
        ax.add_patch(Rectangle((zx, y), Z - 1, Z - 1, fill=False, edgecolor="darkorange", linewidth=1.5 * line))
        if has is None:
            ax.text(zx + Z / 2, y + Z / 2, "no hole", ha="center", va="center", fontsize=0.8 * font, color="0.4")
    for r, label in enumerate(row_labels):
        words = str(label).split()
        if len(words) > 1 and len(str(label)) * 0.6 * 0.125 * H > 0.95 * H:  # too long for the row: two lines
            half = max(1, len(words) // 2)
            label = " ".join(words[:half]) + "\n" + " ".join(words[half:])
        ax.text(label_w * 0.5, head_h + r * (H + gap_row) + H / 2, label, rotation=90, ha="center", va="center",
                fontsize=font, linespacing=1.0)
    title_h = int(0.2 * H) if title else 0
    for c, label in enumerate(column_labels):
        x = label_w + c * (cell_w + gap_out)
        ax.text(x + cell_w / 2, title_h + 0.1 * H, label, ha="center", va="center", fontsize=font)
    if title:
        ax.text(width / 2, 0.1 * H, title, ha="center", va="center", fontsize=font)
    out = Path(out_png)
    with atomic_path(out, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=dpi, facecolor="white")
    plt.close(fig)
    return out
