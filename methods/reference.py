"""Reference fills: the floor (`none`) and the easy temporal win (`temporal-copy`).

These are not methods from the paper. They bracket it: `none` is what every method must beat, and
`temporal-copy` is the simplest use of the neighbouring frames. A temporal method that does not beat
`temporal-copy` does not justify its complexity.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import check_regions_near
from dpcbench.methods._geometry import detect_regions, icp_align  # re-exported: callers import them from here
from dpcbench.methods.base import InpaintingMethod, Regions
from dpcbench.metrics.errors import UserError

# the one nearest-sample spacing estimator (re-exported: tests and callers import it from here)
from dpcbench.metrics.neighbours import median_neighbour_distance


class NoFill(InpaintingMethod):
    """Return copies of the damaged frames unchanged (the score floor).

    It accepts ``regions=None`` (blind protocol) as well: there is nothing to detect when nothing is
    filled, so `detects_holes` is True only in that trivial sense.
    """

    name = "none"
    summary = "no filling: returns the damaged input unchanged (score floor)"
    version = "1"
    detects_holes = True

    def __init__(self) -> None:
        pass

    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        frames, _ = self._check_inputs(frames, regions)
        return [frame.copy() for frame in frames]


class TemporalCopy(InpaintingMethod):
    """Fill each hole of frame f with the points of a neighbouring frame, rigidly aligned.

    For every hole region R of frame f (regions given, or found by `holes.detection.detect_holes`
    when ``regions=None``):

    1. Source frame: f-1 or f+1, whichever has more points inside R (ties -> f-1). When neither
       has any point inside R, the hole is left as it is.
    2. Shell: the points within ``shell`` of R but outside it, with
       ``shell = max(shell_factor * bounding_radius(R), min_shell_spacings * spacing)`` and
       ``spacing`` the median nearest-neighbour distance of frame f.
    3. Alignment: point-to-point ICP (`icp_align`, open3d) of the source
       frame's shell onto frame f's points within ``2 * shell`` of R (which has no points inside R:
       that is the hole), starting from the identity, correspondences farther than ``shell`` dropped.
    4. The source points within ``2 * shell`` of R are moved by that rigid motion; those that land
       inside R (and inside no earlier region of the same frame, so overlapping regions are filled
       once) and farther than ``overlap_spacings * spacing`` from every point frame f still has are
       added to frame f. The last rule keeps a partially emptied region from being filled twice.

    Sources are always the damaged input frames, never already-filled ones, so the result does not
    depend on the order in which frames are processed. A one-frame sequence has no neighbour: it is
    returned unchanged with a warning.
    """

    name = "temporal-copy"
    summary = "copies the hole region from the neighbouring frame (f-1 or f+1) after ICP alignment of its surroundings"
    version = "1"
    uses_neighbour_frames = True
    detects_holes = True

    def __init__(self, shell_factor: float = 0.5, min_shell_spacings: float = 4.0,
                 icp_iterations: int = 30, alignment_rounds: int = 3, overlap_spacings: float = 0.5):
        self.shell_factor = shell_factor
        self.min_shell_spacings = min_shell_spacings
        self.icp_iterations = icp_iterations
        self.alignment_rounds = alignment_rounds
        self.overlap_spacings = overlap_spacings

    def _validate_params(self) -> None:
        if not self.shell_factor >= 0:
            raise UserError(f"temporal-copy: shell_factor must be >= 0, got {self.shell_factor}")
        if not self.min_shell_spacings > 0:
            raise UserError(f"temporal-copy: min_shell_spacings must be > 0, got {self.min_shell_spacings}")
        if int(self.icp_iterations) < 0:
            raise UserError(f"temporal-copy: icp_iterations must be >= 0, got {self.icp_iterations}")
        if not self.overlap_spacings >= 0:
            raise UserError(f"temporal-copy: overlap_spacings must be >= 0, got {self.overlap_spacings}")

    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        return self.inpaint_with_sources(frames, regions)[0]

    def inpaint_with_sources(self, frames: list[np.ndarray], regions: Regions = None) -> tuple[list[np.ndarray], list]:
        """``inpaint``'s output and, per frame, (source frame, source row) of every point: the frame's
        own row for its input points, the neighbour frame and row each copied point came from."""
        self._validate_params()
        frames, regions = self._check_inputs(frames, regions)
        if len(frames) == 1:
            warnings.warn("temporal-copy: a one-frame sequence has no neighbouring frame to copy from; "
                          "returning it unchanged", RuntimeWarning, stacklevel=2)
            return [frames[0].copy()], [_own_rows(0, len(frames[0]))]
        if regions is None:
            regions = detect_regions(frames, self.name)
        filled = [self._fill_frame(frames, f, regions[f]) for f in range(len(frames))]
        return [points for points, _ in filled], [sources for _, sources in filled]

    def _fill_frame(self, frames, f, frame_regions) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        target = frames[f]
        own = _own_rows(f, len(target))
        if not frame_regions:
            return target.copy(), own
        target_tree = cKDTree(target)
        spacing = median_neighbour_distance(target, tree=target_tree)
        neighbours = [n for n in (f - 1, f + 1) if 0 <= n < len(frames)]
        fills: list[np.ndarray] = []
        sources: list[tuple[np.ndarray, np.ndarray]] = []
        shells = [max(self.shell_factor * r.bounding_radius, self.min_shell_spacings * spacing) for r in frame_regions]
        # a region farther from the cloud than its shell reaches finds nothing to align: refuse it
        # (like temporal-graph) rather than add 0 points and look successful
        check_regions_near(target, frame_regions, [2 * s for s in shells], tree=target_tree, who=self.name,
                           frame_index=f)
        for k, region in enumerate(frame_regions):
            counts = [int(region.contains(frames[n]).sum()) for n in neighbours]
            if max(counts) == 0:
                continue
            source_frame = neighbours[int(np.argmax(counts))]  # argmax takes the first on ties: f-1
            source = frames[source_frame]
            shell = shells[k]

            near_rows = np.flatnonzero(region.contains(source, margin=2 * shell))
            source_near = source[near_rows]
            target_near = target[region.contains(target, margin=2 * shell)]
            rotation, translation = np.eye(3), np.zeros(3)
            for _ in range(max(1, int(self.alignment_rounds))):
                # the shell is chosen where the source points land *after* the current alignment,
                # so source points that belong to frame f's hole do not pull the fit towards its rim
                moved = source_near @ rotation.T + translation
                in_shell = ~region.contains(moved) & region.contains(moved, margin=shell)
                rotation, translation = icp_align(source_near[in_shell], target_near, max_distance=shell,
                                                  max_iterations=int(self.icp_iterations),
                                                  init=(rotation, translation))
            moved = source_near @ rotation.T + translation
            inside = region.contains(moved)
            for earlier in frame_regions[:k]:
                inside &= ~earlier.contains(moved)
            candidates = moved[inside]
            rows = near_rows[inside]
            if len(candidates) and self.overlap_spacings > 0:
                gap, _ = target_tree.query(candidates, k=1)
                far = gap > self.overlap_spacings * spacing
                candidates, rows = candidates[far], rows[far]
            fills.append(candidates)
            sources.append((np.full(len(rows), source_frame, dtype=np.intp), rows))
        if not fills:
            return target.copy(), own
        return (np.concatenate([target, *fills], axis=0),
                (np.concatenate([own[0], *(s[0] for s in sources)]), np.concatenate([own[1], *(s[1] for s in sources)])))


def _own_rows(f: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Sources of a frame's own n input points: (frame f, rows 0..n-1)."""
    return np.full(n, f, dtype=np.intp), np.arange(n)


__all__ = ["NoFill", "TemporalCopy", "detect_regions", "icp_align", "median_neighbour_distance"]
