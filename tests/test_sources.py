"""Sequence sources behind one interface and one resolver (`bench.data.sources`, `bench.data.datasets.resolve_source`)."""

from __future__ import annotations

import numpy as np
import pytest

import dpcbench.bench.data.datasets as datasets
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.datasets import load_dataset, load_run_sequence, resolve_source
from dpcbench.bench.data.plyio import PointCloud, write_ply
from dpcbench.bench.data.sequences import Sequence, coarsen_voxels
from dpcbench.bench.data.sources import SequenceSource, frame_indices
from dpcbench.bench.data.sources.embedded import EmbeddedSource
from dpcbench.bench.data.sources.meshes import MeshDatasetSource, MeshFolderSource
from dpcbench.bench.data.sources.paper import PaperSource
from dpcbench.bench.data.sources.points import PointCloudSource


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("DPCBENCH_QUIET", "1")
    monkeypatch.delenv(datasets.DATA_DIR_ENV, raising=False)


def _ply_folder(folder, frames=4, n=150):
    for i in range(frames):
        rng = np.random.default_rng(i)
        write_ply(folder / f"f_{i}.ply", PointCloud(rng.integers(0, 512, size=(n, 3)).astype(np.float64)))
    return folder


def _obj_folder(folder, frames=2):
    folder.mkdir(parents=True)
    for i in range(frames):  # a unit tetrahedron moving along x
        v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) + [0.1 * i, 0, 0]
        lines = [f"v {x} {y} {z}" for x, y, z in v] + ["f 1 3 2", "f 1 2 4", "f 1 4 3", "f 2 3 4"]
        (folder / f"m_{i}.obj").write_text("\n".join(lines) + "\n")
    return folder


def test_the_resolver_picks_each_kind(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    plys = _ply_folder(tmp_path / "plys")
    meshes = _obj_folder(tmp_path / "meshes")
    assert isinstance(resolve_source("human"), EmbeddedSource)
    assert isinstance(resolve_source("Bunny"), EmbeddedSource)
    assert isinstance(resolve_source("longdress", tmp_path), PaperSource)
    assert isinstance(resolve_source("samba"), MeshDatasetSource)
    folder = resolve_source(meshes)
    assert isinstance(folder, MeshFolderSource) and folder.name == "meshes" and len(folder.files) == 2
    points = resolve_source(plys, label="My capture")
    assert isinstance(points, PointCloudSource) and points.name == "My capture"
    assert isinstance(resolve_source(str(plys / "*.ply")), PointCloudSource)
    with pytest.raises(UserError, match="not a dataset name and no such file or folder"):
        resolve_source("no-such-thing")
    # a folder named like a dataset in the working directory shadows the name, except for configs
    _ply_folder(tmp_path / "human", frames=1)
    with pytest.warns(UserWarning, match="is both the embedded sequence human"):
        assert isinstance(resolve_source("human"), PointCloudSource)
    assert isinstance(resolve_source("human", name_only=True), EmbeddedSource)


def test_sources_load_the_frames_asked_for(tmp_path):
    plys = _ply_folder(tmp_path / "plys")
    seq = resolve_source(plys).load([3, 1], progress=False)
    assert isinstance(seq, Sequence) and [p.name for p in seq.files] == ["f_3.ply", "f_1.ply"]
    np.testing.assert_array_equal(seq.frames[0].points, load_dataset(plys, frames=[3]).frames[0].points)
    with pytest.raises(UserError, match="unknown parameter.*size of PLY frames"):
        resolve_source(plys).load(size="tiny")
    with pytest.raises(UserError, match="frame 9 requested but the sequence has 4 frames"):
        resolve_source(plys).load([9])
    meshes = resolve_source(_obj_folder(tmp_path / "meshes")).load(1, progress=False, points=300, bit_depth=None,
                                                                   cache=False)
    assert len(meshes) == 1 and abs(len(meshes.frames[0].points) - 300) <= 3 and meshes.motion is not None
    with pytest.raises(UserError, match="unknown mesh sequence parameter"):
        resolve_source(tmp_path / "meshes").load(size="tiny")


def test_run_specs_load_through_the_same_resolver(tmp_path):
    plys = _ply_folder(tmp_path / "plys")
    by_path = load_run_sequence({"name": "plys", "path": str(plys), "label": "Capture", "frames": [1, 3],
                                 "params": {}})
    assert by_path.name == "Capture" and [p.name for p in by_path.files] == ["f_1.ply", "f_2.ply"]
    by_name = load_run_sequence({"name": "human", "params": {"size": "tiny"}, "frames": 2})
    direct = load_dataset("human", frames=2, size="tiny")
    assert by_name.name == "human" and len(by_name) == 2
    for a, b in zip(by_name.frames, direct.frames):
        np.testing.assert_array_equal(a.points, b.points)


def test_a_new_source_is_one_subclass():
    """The interface a new kind of source implements: ``name``, ``kind``, ``load`` -> Sequence."""

    class Spiral(SequenceSource):
        kind = "spiral"

        def load(self, frames=None, *, progress=True, turns: float = 1.0):
            indices = frame_indices(frames if frames is not None else 3, None, self.name)
            t = np.linspace(0, 2 * np.pi * turns, 50)
            clouds = [PointCloud(np.c_[np.cos(t), np.sin(t), t + i]) for i in indices]
            return Sequence(self.name, clouds)

    seq = Spiral("spiral").load([0, 2], turns=2.0)
    assert len(seq) == 2 and seq.frames[1].points[0, 2] == 2.0
    with pytest.raises(UserError, match="frame indices must be >= 0"):
        Spiral("spiral").load([-1])


def _coarsened_by_hand(points, colors, size):
    """`coarsen_voxels` spelled out: a dict from voxel to the colours that fall into it."""
    cells: dict[tuple, list] = {}
    for point, colour in zip(points, colors):
        cells.setdefault(tuple(int(c) // size for c in point), []).append(colour)
    keys = sorted(cells)
    means = [np.rint(np.mean(np.asarray(cells[k], dtype=np.float64), axis=0)) for k in keys]
    return np.asarray(keys, dtype=np.float64), np.asarray(means, dtype=np.uint8)


def test_a_voxelized_frame_re_voxelized_on_a_coarser_grid_is_the_rule_spelled_out(tmp_path):
    rng = np.random.default_rng(3)
    points = rng.integers(0, 64, size=(2_000, 3)).astype(np.float64)  # many voxels of 2 and 4 hold several points
    colors = rng.integers(0, 256, size=(2_000, 3)).astype(np.uint8)
    normals = rng.normal(size=(2_000, 3))
    write_ply(tmp_path / "plys" / "f_0.ply", PointCloud(points, colors, normals))
    for size in (2, 4, 5):
        seq = load_dataset(tmp_path / "plys", voxel_size=size)
        expected_points, expected_colors = _coarsened_by_hand(points, colors, size)
        frame = seq.frames[0]
        np.testing.assert_array_equal(frame.points, expected_points)
        np.testing.assert_array_equal(frame.colors, expected_colors)
        assert frame.normals is None and seq.meta["voxel_size"] == size
        assert seq.bit_depth == int(np.ceil(np.log2(expected_points.max() + 1)))
    same = load_dataset(tmp_path / "plys", voxel_size=1).frames[0]
    np.testing.assert_array_equal(same.points, points)
    # two halvings are one quartering (the points; a mean of means is not the mean)
    twice = coarsen_voxels(coarsen_voxels(PointCloud(points, colors), 2), 2)
    np.testing.assert_array_equal(twice.points, load_dataset(tmp_path / "plys", voxel_size=4).frames[0].points)


def test_only_voxelized_frames_take_a_coarser_grid(tmp_path):
    write_ply(tmp_path / "floats" / "f_0.ply", PointCloud(np.random.default_rng(0).normal(size=(50, 3))))
    with pytest.raises(UserError, match="re-voxelizes voxelized frames.*leave voxel_size out"):
        load_dataset(tmp_path / "floats", voxel_size=2)
    plys = _ply_folder(tmp_path / "plys")
    for bad in (0, 1.5, True, "2"):
        with pytest.raises(UserError, match="voxel_size must be an integer >= 1"):
            resolve_source(plys).load(voxel_size=bad)


def test_a_damage_of_re_voxelized_frames_is_refused_on_the_frames_read_otherwise(tmp_path):
    """holes.json records the voxel_size its frames were read with; used on the same files read at another size
    (its regions are in the other grid's units) it is refused with a one-line message."""
    import json

    from dpcbench.bench.data.sequences import check_regions_frames, frames_record

    plys = _ply_folder(tmp_path / "plys", frames=2)
    coarse = load_dataset(plys, voxel_size=2)
    holes = tmp_path / "holes.json"
    holes.write_text(json.dumps({"frames": [{"regions": []}] * 2, **frames_record(coarse)}))
    assert json.loads(holes.read_text())["input_voxel_size"] == 2
    check_regions_frames(holes, load_dataset(plys, voxel_size=2), "--regions")  # read as the damage did
    with pytest.raises(UserError, match="voxel_size=2, but they are read with voxel_size=1") as err:
        check_regions_frames(holes, load_dataset(plys), "--regions")
    assert "\n" not in str(err.value)
    holes.write_text(json.dumps({"frames": [{"regions": []}] * 2, **frames_record(load_dataset(plys))}))
    assert "input_voxel_size" not in json.loads(holes.read_text())  # the frames as they are: nothing recorded
    with pytest.raises(UserError, match="voxel_size=1, but they are read with voxel_size=4"):
        check_regions_frames(holes, load_dataset(plys, voxel_size=4), "--regions")
