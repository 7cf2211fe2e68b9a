"""Hole generators (damage with ground truth) and hole detection, on plain numpy arrays.

A frame is an (N, 3) float array; a sequence is a list of them. Nothing here depends on `bench`.

- `holes.regions`:   HoleRegion (ball / oriented box), holes.json format.
- `holes.base`:      HoleGenerator interface, DamageResult, shared validation.
- `holes.synthetic`: "region" (ball/cube holes sized in the method's cube M; presets; coherent
                     tracking) and "dropout" (many small holes).
- `holes.occlusion`: "occlusion" (what a simulated camera rig does not see; a z-buffer of splats, or open3d HPR).
- `holes.detection`: detect_holes for captured frames without ground truth; detection_scores.
- `holes.geometry`:  point spacing, cube size M, connected pieces -> regions, normals.
- `holes.registry`:  GENERATORS name -> class ("none": `holes.base.NoHoles`, the data's own holes).
- `holes.lazy`:      the lazy name -> "module:Attr" registry that holes and methods share.
"""

from dpcbench.holes.regions import HoleRegion, regions_from_json, regions_to_json

__all__ = ["HoleRegion", "regions_from_json", "regions_to_json"]
