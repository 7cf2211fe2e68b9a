"""The interface every inpainting method implements.

Convention (after scikit-learn's estimators): ``__init__`` takes keyword parameters with defaults
and only stores them under the same names; all the work happens in `inpaint`. `get_params` reads
the parameters back from the ``__init__`` signature, so configs and result records can store them.

``inpaint(frames, regions=None)``:
  frames:  list of F arrays of shape (N_f, 3), the damaged sequence. Never modified. Through
           `check_sequence` (``self._check_inputs``) a frame may also be an array of another real
           dtype or an ``open3d.geometry.PointCloud`` (`metrics.points.as_points`).
  regions: None (blind: the method finds the missing data itself, if it can) or a list of F lists
           of `holes.regions.HoleRegion`, the hole regions of each frame. A method never receives
           the removed ground-truth points: the interface has no way to pass them.
  returns: a new list of F arrays of shape (N'_f, 3), float64, all finite.

Colour (8-bit RGB per point, (N_f, 3) uint8 beside each frame) is a parallel array, never passed to
``inpaint``: `InpaintingMethod.inpaint_with_colours` runs ``inpaint`` and colours its output with a
generic fill (`methods._colour`: kept points keep their colour; new points take the colour of the
source point the method reports, `inpaint_with_sources`, or the nearest input colour, or a harmonic
interpolation from the hole's rim). So every method and adapter carries colour, and its geometry is
exactly that of ``inpaint``. A method whose colours are not one input point's each (temporal-fusion fuses
several copies' colours and carries its previous frame's; temporal-graph and fu-nonlocal solve colour on
their graph; meshlab takes MeshLab's interpolated vertex colours) overrides ``inpaint_with_colours`` itself
(`colours_itself`): its geometry must stay exactly ``inpaint``'s, and the generic fills ("nearest",
"harmonic") stay available through this base method.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.progress import frame_done
from dpcbench.metrics.errors import UserError
from dpcbench.metrics.params import Parameterized
from dpcbench.metrics.points import as_points, is_point_cloud_object

#: the hole regions of each frame (F lists), or None (blind: the method finds the holes itself)
Regions = Sequence[Sequence[HoleRegion]] | None


class InpaintingMethod(Parameterized):
    name: ClassVar[str] = ""
    #: short human description shown by `dpcbench list`
    summary: ClassVar[str] = ""
    #: bump when a change alters the output: results stored under another version are recomputed
    version: ClassVar[str] = "1"
    #: True when frame f's result depends on frames other than f
    uses_neighbour_frames: ClassVar[bool] = False
    #: True when the method cannot run without hole regions
    needs_regions: ClassVar[bool] = False
    #: True when the method can find the missing data itself (blind protocol, regions=None)
    detects_holes: ClassVar[bool] = False

    _kind: ClassVar[str] = "method"
    #: the class's own parameter checks (``validate_params`` runs the first one it defines)
    _param_hooks: ClassVar[tuple[str, ...]] = ("_validate_params", "_validate")

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        raise NotImplementedError

    def inpaint_with_sources(self, frames: list[np.ndarray], regions: Regions = None) -> tuple[list[np.ndarray], list | None]:
        """(``inpaint``'s output, sources): sources is None, or per output frame a pair of (N'_f,) int
        arrays (source frame, source row in that input frame) saying which input point each output
        point was copied from (-1, -1 for a point made by the method). A method that copies points
        (temporal-copy) overrides this; its output must stay exactly ``inpaint``'s."""
        return self.inpaint(frames, regions), None

    def inpaint_with_colours(self, frames: list[np.ndarray], colours: Sequence[np.ndarray], regions: Regions = None,
                             *, fill: str = "auto") -> tuple[list[np.ndarray], list[np.ndarray]]:
        """(points, colours): ``inpaint``'s output and an (N'_f, 3) uint8 colour per output point.

        colours: F arrays (N_f, 3) of the input frames' RGB. fill (`methods._colour.FILLS`):
        "nearest" (each new point its nearest input point's colour), "harmonic" (graph-harmonic
        interpolation from the rim), "source" (the reported source point's colour, else nearest),
        "auto" (source where reported, else harmonic)."""
        from dpcbench.methods._colour import colour_outputs

        checked, colours = self._check_colours(frames, colours, regions, fill)
        outputs, sources = self.inpaint_with_sources(frames, regions)
        return outputs, colour_outputs(checked, colours, outputs, sources, fill)

    def _check_colours(self, frames: Sequence[np.ndarray], colours: Sequence[np.ndarray], regions: Regions,
                       fill: str) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """(the frames as float64 (N_f, 3) views, ``colours`` as F (N_f, 3) uint8 arrays matching them); UserError
        for an unknown ``fill`` or colours that do not match the frames (a method overriding
        `inpaint_with_colours` checks its input with this)."""
        from dpcbench.methods._colour import FILLS, check_colour_frames

        if fill not in FILLS:
            raise UserError(f"{self.name}: unknown colour fill {fill!r}; choose one of {', '.join(FILLS)}")
        checked, _ = check_sequence(frames, regions, method=self.name, needs_regions=False, detects_holes=True)
        return checked, check_colour_frames(checked, colours, self.name)

    # -- helpers shared by every method ------------------------------------------------------
    def _check_inputs(self, frames: Sequence[np.ndarray], regions: Regions) -> tuple[list[np.ndarray], list | None]:
        """Validate the sequence and regions; return float64 views (inputs are never written)."""
        return check_sequence(frames, regions, method=self.name, needs_regions=self.needs_regions,
                              detects_holes=self.detects_holes)


def colours_itself(method) -> bool:
    """Whether ``method`` colours its output itself (its class overrides `InpaintingMethod.inpaint_with_colours`,
    as temporal-fusion does): a caller that has colours then asks it for them rather than colouring
    ``inpaint_with_sources``' output with the generic fill."""
    own = getattr(type(method), "inpaint_with_colours", None)
    return own is not None and own is not InpaintingMethod.inpaint_with_colours


class PerFrameMethod(InpaintingMethod):
    """A method that inpaints each frame on its own: implement `inpaint_frame`."""

    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        frames, regions = self._check_inputs(frames, regions)
        out = []
        for i, frame in enumerate(frames):
            frame_regions = None if regions is None else regions[i]
            if frame_regions is not None and len(frame_regions) == 0:
                out.append(frame.copy())
            else:
                out.append(np.asarray(self.inpaint_frame(frame, frame_regions), dtype=np.float64))
            frame_done(i + 1, len(frames))
        return out

    def inpaint_frame(self, points: np.ndarray, regions: Sequence[HoleRegion] | None) -> np.ndarray:
        raise NotImplementedError


def check_sequence(frames: Sequence[np.ndarray], regions: Regions = None, *, method: str = "method",
                   needs_regions: bool = False, detects_holes: bool = True) -> tuple[list[np.ndarray], list | None]:
    """Shared input validation with messages that say what is wrong and what to do."""
    if (isinstance(frames, np.ndarray) and frames.ndim == 2) or is_point_cloud_object(frames):
        raise UserError(f"{method}: expected a list of (N, 3) frames, got one array; wrap it: [frame]")
    frames = list(frames)
    if not frames:
        raise UserError(f"{method}: the sequence has no frames")
    checked = []
    for i, frame in enumerate(frames):
        arr = as_points(frame)
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise UserError(f"{method}: frame {i} must be an (N, 3) array, got shape {arr.shape}")
        if len(arr) == 0:
            raise UserError(f"{method}: frame {i} has zero points; drop empty frames before inpainting")
        if not np.isfinite(arr).all():
            raise UserError(f"{method}: frame {i} has NaN or infinite coordinates; remove those points first")
        checked.append(arr)
    if regions is None:
        if needs_regions or not detects_holes:
            raise UserError(
                f"{method}: needs the hole regions (regions=None is the blind protocol, which this method "
                "does not support); pass regions from holes.json or run hole detection first"
            )
        return checked, None
    regions = list(regions)
    if len(regions) != len(checked):
        raise UserError(f"{method}: got {len(regions)} region lists for {len(checked)} frames; give one list per frame")
    return checked, [list(r) for r in regions]
