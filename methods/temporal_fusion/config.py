"""temporal-fusion's parameters: one frozen record (`FusionConfig`), each field with its declared constraint
(type, range) and one line of rationale, and the table of ablation switches (`ABLATIONS`) that only restore an
older behaviour. `TemporalFusion.__init__` keeps the same keyword parameters (the harness reads them with
``get_params``); `FusionConfig.of` checks them against the constraints here and freezes them."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from dpcbench.holes.regions import HoleRegion


@dataclass(frozen=True)
class Constraint:
    """A parameter's declared contract: ``kind`` ("int", "number", "bool", "neighbours", "snap"), the least
    value (``least``, ``strict``: > rather than >=; numbers and integers only) and one line of rationale."""

    kind: str
    rationale: str
    least: float | None = None
    strict: bool = False

    def problem(self, name: str, value: Any) -> str | None:
        """The one-line complaint about ``value`` for parameter ``name``, or None when it is allowed."""
        if self.kind == "bool":
            return None if isinstance(value, bool) else f"{name} must be true or false, got {value!r}"
        if self.kind == "snap":
            return None if value in ("auto", True, False) else f"snap must be 'auto', true or false, got {value!r}"
        integer = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
        if self.kind == "neighbours":
            if value == "auto" or (integer and value >= 0):
                return None
            return f"mls_neighbours must be 'auto' or an integer >= 0, got {value!r}"
        if self.kind == "int":
            return None if integer and value >= self.least else f"{name} must be an integer >= {self.least:g}, got {value!r}"
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        ok = number and (value > self.least if self.strict else value >= self.least)
        return None if ok else f"{name} must be a number {'>' if self.strict else '>='} {self.least:g}, got {value!r}"


def _knob(default: Any, kind: str, rationale: str, least: float | None = None, strict: bool = False) -> Any:
    from dataclasses import field

    return field(default=default, metadata={"constraint": Constraint(kind, rationale, least, strict)})


@dataclass(frozen=True)
class FusionConfig:
    """The parameters of one temporal-fusion run, checked and frozen. Lengths are in point spacings s or hole
    radii r, time in frames."""

    window: int = _knob(3, "int", "at 30 fps a hole's patch is seen again within +-0.1 s; farther frames "
                        "deform too much for a rim-driven correction", 0)
    shell_factor: float = _knob(0.5, "number", "rim width in hole radii: wide enough to fix a rotation", 0)
    shell_spacings: float = _knob(4.0, "number", "least rim width in spacings: a few rows of samples", 0, True)
    surface_shell_spacings: float = _knob(4.0, "number", "least width of the rim the spatial surfaces are fitted to "
                                          "and held out on (at most the rim's own): the rim's floor; 2 gained only on "
                                          "one frame of a coarse capture (docs, 'Held-out sizes')", 0, True)
    icp_iterations: int = _knob(30, "int", "ICP iterations a call (open3d stops earlier at convergence)", 0)
    accept_spacings: float = _knob(1.0, "number", "rim residual bound: two samplings of one surface lie about "
                                   "half a spacing apart, a wrong match a spacing or more", 0, True)
    refine: bool = _knob(True, "bool", "point-to-plane refinement of the rigid motion (pairs within 2 s)")
    deform: bool = _knob(True, "bool", "bend the rigid copy by the rim's normal residual (Shepard interpolation)")
    deform_neighbours: int = _knob(32, "int", "rim residuals averaged per point: a sample's own +-0.5 s "
                                   "offset averages out (1 / sqrt(32) of it is left)", 1)
    gap_spacings: float = _knob(0.5, "number", "a copied point nearer than half a spacing to a captured one "
                                "duplicates it", 0)
    fill_gap_spacings: float = _knob(1.0, "number", "a reused or spatial point nearer than a spacing to an "
                                     "accepted one samples the same surface element", 0)
    reuse_previous: bool = _knob(True, "bool", "a persistent hole's surface is the same surface, moved (stage reuse)")
    fallback: bool = _knob(True, "bool", "the spatial cascade where no frame saw the surface (False leaves it open)")
    surface_holdout_spacings: float = _knob(1.0, "number", "a surface that misses the rim's own inner ring by a "
                                            "spacing or more is a wrong surface", 0, True)
    mls_neighbours: int | str = _knob("auto", "neighbours", "points of a quadric fit: 'auto' is 20 (6 "
                                      "coefficients over-determined ~3 times), 28 for voxel decisions (a disc of 3 s)")
    rim_fill: bool = _knob(True, "bool", "thin voxel gaps grown from frame f's own rim (stage rim_fill)")
    poisson: bool = _knob(True, "bool", "closed-surface (screened Poisson) fill where the height field refuses")
    poisson_bodies: bool = _knob(True, "bool", "reconstruct each connected body of the crop alone")
    poisson_bridges: bool = _knob(True, "bool", "span a limb the hole cuts through in the tube's chart")
    cap: bool = _knob(True, "bool", "membrane across an opening no surface round it continues (voxelized input)")
    harmonic_cap: bool = _knob(True, "bool", "the cap is the harmonic height field of its loop, built afresh a frame")
    walled_cap_first: bool = _knob(True, "bool", "cap before the closed surface where walls rise from a shallow opening")
    membrane: bool = _knob(True, "bool", "graph membrane across the open parts of a region (occlusion boxes)")
    front: bool = _knob(False, "bool", "advancing front where every other spatial fill refused: off, as it costs "
                        "D2 below no fill")
    partial_sources: bool = _knob(True, "bool", "what frames with their own hole near R saw of it")
    sheet: bool = _knob(True, "bool", "the spline fill retried on the hole's own sheet of the crop")
    revoxelize: bool = _knob(True, "bool", "copies re-voxelized by the capture's rule (voxelized input)")
    pool_adjacent: bool = _knob(True, "bool", "the re-voxelization's fit also takes f-1's and f+1's copies")
    adjacent_first: bool = _knob(True, "bool", "frames beyond f+-1 only where f-1 and f+1 are not both sources")
    count_copies: bool = _knob(True, "bool", "the re-voxelization keeps as many voxels as the copies hold")
    reuse_next: bool = _knob(True, "bool", "holes left open take frame f+1's fill moved back (stage back_fill)")
    drop_layers: bool = _knob(True, "bool", "no second layer over the captured surface inside an occlusion box")
    coarse_retry: bool = _knob(True, "bool", "an alignment that misses the bound is retried coarse to fine")
    poisson_in_boxes: bool = _knob(True, "bool", "try the closed-surface fill in regions that keep captured points "
                                   "(False: 3-10x faster on real captures with occlusion boxes)")
    membrane_after_poisson: bool = _knob(True, "bool", "the membrane also spans what the closed surface left open "
                                         "in a region that keeps captured points")
    best_surface: bool = _knob(True, "bool", "a hole every spatial strategy refused takes the candidate surface with "
                               "the least hold-out miss, unless leaving it open is predicted to cost less D1")
    snap: bool | str = _knob("auto", "snap", "voxelize the output when the input is voxelized: integer coordinates "
                             "at a spacing of at most 1.5 voxels (True/False force it)")

    @classmethod
    def of(cls, params: dict[str, Any], method: str = "temporal-fusion") -> FusionConfig:
        """The config of ``params`` (a method's ``get_params()``); ValueError naming the first parameter that
        breaks its constraint."""
        for item in fields(cls):
            problem = item.metadata["constraint"].problem(item.name, params[item.name])
            if problem:
                raise ValueError(f"{method}: {problem}")
        return cls(**{item.name: params[item.name] for item in fields(cls)})

    # -- derived values ---------------------------------------------------------------------------
    def shell(self, region: HoleRegion, spacing: float) -> float:
        """The rim width: max(shell_factor r, shell_spacings s)."""
        return max(self.shell_factor * region.bounding_radius, self.shell_spacings * spacing)

    def surface_shell(self, region: HoleRegion, spacing: float) -> float:
        """The width of the rim the spatial surfaces see: max(shell_factor r, surface_shell_spacings s), at most
        the rim's own (`shell`)."""
        return min(self.shell(region, spacing),
                   max(self.shell_factor * region.bounding_radius, self.surface_shell_spacings * spacing))

    def fit_neighbours(self, voxelized: bool) -> int:
        """``mls_neighbours`` resolved: "auto" is `VOXEL_FIT_NEIGHBOURS` for voxel decisions on voxelized input
        (``voxelized``), else `FIT_NEIGHBOURS`."""
        if self.mls_neighbours == "auto":
            return VOXEL_FIT_NEIGHBOURS if voxelized else FIT_NEIGHBOURS
        return int(self.mls_neighbours)


def constraints() -> dict[str, Constraint]:
    """Parameter name -> its declared `Constraint`, in signature order."""
    return {item.name: item.metadata["constraint"] for item in fields(FusionConfig)}


def rim_fill_rounds(neighbours: int) -> int:
    """Rounds of a fill grown from the rim: one fit radius, ceil(sqrt(k / pi)) spacings, the radius of the disc
    that the k = ``neighbours`` (at least 6) points of a fit cover at one point per s^2 (3 for k = 20 and 28): the
    rim's surface is extrapolated no farther than the data it is fitted to spans."""
    return max(1, int(math.ceil(math.sqrt(max(int(neighbours), 6) / math.pi))))


#: points of an MLS quadric fit (``mls_neighbours="auto"``): 20, the quadric's 6 coefficients over-determined about
#: 3 times (a disc of ~2.5 s); for voxel decisions on voxelized input 28, the points of a disc of 3 s (pi 3^2):
#: captured voxel centres carry the capture's rounding, up to half a voxel on each axis, which more points average
FIT_NEIGHBOURS = 20
VOXEL_FIT_NEIGHBOURS = 28


#: The ablation switches: each is True by default, and False restores the behaviour the pipeline had before the
#: step was added (for measuring what the step buys; docs/temporal-fusion.md has each one's decision record). The
#: other parameters are the user's knobs.
ABLATIONS: dict[str, str] = {
    "rim_fill": "thin voxel gaps filled by the copies and the spatial cascade like any other hole",
    "revoxelize": "copies and reused points rounded to their nearest voxel",
    "partial_sources": "frames with their own hole near R give no points",
    "poisson": "no closed-surface fill: what the height field refuses stays open (or goes to the cap / membrane)",
    "poisson_bodies": "one Poisson reconstruction of the whole crop",
    "poisson_bridges": "a limb cut through is reconstructed body by body (each end capped)",
    "cap": "no cap across openings",
    "harmonic_cap": "the cap is a thin-plate spline through its loop, and reused by the next frame",
    "walled_cap_first": "the closed surface is tried before the cap everywhere",
    "membrane": "no graph membrane",
    "membrane_after_poisson": "in a box, any closed-surface fill ends the cascade",
    "sheet": "no retry of the spline fill on the hole's own sheet",
    "pool_adjacent": "the re-voxelization's fit rests on the first copy only",
    "adjacent_first": "every frame in the window is aligned",
    "count_copies": "the re-voxelization keeps the voxels under the rim's crossing bound",
    "reuse_next": "no back-fill from frame f+1",
    "drop_layers": "second layers over the captured surface are kept",
    "coarse_retry": "no coarse-to-fine retry of a failed alignment",
    "best_surface": "a hole every spatial strategy refused stays open",
}
