"""Frames as researchers hold them, in and out of the numpy API.

Everywhere a frame is accepted (`metrics.score_frame`, `metrics.score_sequence`, a method's
``inpaint``), it may be an (N, 3) array of any real dtype (float32 included: converted to float64),
a nested list, or an ``open3d.geometry.PointCloud`` (anything with a ``points`` attribute that numpy
can read); a sequence is a list of them. Results are numpy: `to_open3d` turns a frame, or a list of
frames, into open3d point clouds.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def is_point_cloud_object(obj: Any) -> bool:
    """True for a cloud object that carries its coordinates in ``.points`` (open3d's PointCloud,
    `bench.data.plyio.PointCloud`), as opposed to an array-like."""
    return not isinstance(obj, np.ndarray) and hasattr(obj, "points")


def as_points(frame: Any) -> np.ndarray:
    """The coordinates of one frame as a float64 array (a view when the input already is one; no
    copy is made otherwise than to convert). The shape is not checked here: callers check it with
    their own message."""
    if is_point_cloud_object(frame):
        frame = frame.points  # open3d: a Vector3dVector, read by numpy through the buffer protocol
    return np.asarray(frame, dtype=np.float64)


def to_open3d(frames: Any):
    """An ``open3d.geometry.PointCloud`` of an (N, 3) frame, or a list of them for a list of frames
    (the output of ``inpaint``). The coordinates are copied (open3d keeps its own)."""
    import open3d as o3d  # lazily: heavy, and only this helper needs it

    def one(points: Any):
        arr = np.ascontiguousarray(as_points(points))
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise ValueError(f"to_open3d: a frame must be an (N, 3) array, got shape {arr.shape}")
        return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(arr.copy()))

    if isinstance(frames, np.ndarray) or is_point_cloud_object(frames):
        return one(frames)
    return [one(frame) for frame in frames]
