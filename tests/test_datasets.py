"""The dataset registry: embedded names (with cache), paper sequences from a data folder, user folders."""

from __future__ import annotations

import numpy as np
import pytest

import dpcbench.bench.data.datasets as datasets
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.datasets import PAPER, load_dataset, parse_frames, parse_params
from dpcbench.bench.data.plyio import PointCloud, write_ply


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("DPCBENCH_QUIET", "1")
    monkeypatch.delenv(datasets.DATA_DIR_ENV, raising=False)


def voxel_cloud(seed: int, n: int = 200) -> PointCloud:
    rng = np.random.default_rng(seed)
    return PointCloud(rng.integers(0, 1024, size=(n, 3)).astype(np.float64),
                      rng.integers(0, 256, size=(n, 3)).astype(np.uint8))


def make_longdress(root, frames=3, case="longdress"):
    folder = root / case / "Ply"
    for i in range(frames):
        write_ply(folder / f"longdress_vox10_{1051 + i}.ply", voxel_cloud(i))
    return folder


def test_embedded_human_sequence_and_cache(monkeypatch):
    seq = load_dataset("human", frames=2, size="tiny")
    assert seq.name == "human" and len(seq) == 2 and seq.bit_depth == 10
    assert seq.meta["params"]["size"] == "tiny" and seq.meta["frame_indices"] == [0, 1]
    assert all(f.colors is not None and f.points.dtype == np.float64 for f in seq.frames)

    # a second load is served by the cache: the generator is not called, the data are identical
    import functools

    import dpcbench.bench.data.standins.human as human

    @functools.wraps(human.generate_frame)  # keeps the signature the registry reads parameters from
    def refuse(*args, **kwargs):
        raise AssertionError("generator called although the frame is cached")

    monkeypatch.setattr(human, "generate_frame", refuse)
    again = load_dataset("HUMAN", frames=[0, 1], size="tiny")
    for a, b in zip(seq.frames, again.frames):
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.colors, b.colors)
    with pytest.raises(AssertionError, match="generator called"):
        load_dataset("human", frames=[2], size="tiny")  # not cached yet


def test_embedded_frame_selection_matches_full_run():
    some = load_dataset("human", frames=[3, 1], size="tiny", motion="wave", cache=False)
    full = load_dataset("human", frames=4, size="tiny", motion="wave", cache=False)
    np.testing.assert_array_equal(some.frames[0].points, full.frames[3].points)
    np.testing.assert_array_equal(some.frames[1].points, full.frames[1].points)


def test_embedded_bad_parameters():
    with pytest.raises(UserError, match="unknown parameter.*colour.*accepted: motion"):
        load_dataset("human", frames=1, colour="red")
    with pytest.raises(UserError, match="unknown size"):
        load_dataset("bunny", frames=1, size="huge")
    with pytest.raises(UserError, match="at least 1"):
        load_dataset("human", frames=0)


def test_unknown_name_lists_the_known_ones():
    with pytest.raises(UserError) as err:
        load_dataset("longdres")
    message = str(err.value)
    assert "human" in message and "longdress" in message and "folder" in message


def test_paper_sequence_without_data_says_where_to_get_it():
    with pytest.raises(UserError) as err:
        load_dataset("longdress", frames=2)
    message = str(err.value)
    assert "plenodb.jpeg.org" in message and "non-commercial" in message
    assert "longdress_vox10_1051.ply" in message and "--data-dir" in message
    with pytest.raises(UserError, match="ulliwegner|UlliWegner"):
        load_dataset("UlliWegner")


def test_paper_sequence_missing_files_are_named(tmp_path):
    make_longdress(tmp_path, frames=2)
    with pytest.raises(UserError) as err:
        load_dataset("longdress", frames=5, data_dir=tmp_path)
    message = str(err.value)
    assert "3 of the 5" in message and "longdress_vox10_1053.ply" in message
    with pytest.raises(UserError, match="does not exist"):
        load_dataset("loot", data_dir=tmp_path / "nowhere")
    with pytest.raises(UserError, match="no loot PLY frames"):
        load_dataset("loot", data_dir=tmp_path)


def test_paper_sequence_loads_from_data_dir_and_env(tmp_path, monkeypatch):
    make_longdress(tmp_path, frames=3, case="Longdress")  # folder names match case-insensitively
    seq = load_dataset("longdress", frames=[2, 0], data_dir=tmp_path)
    assert [p.name for p in seq.files] == ["longdress_vox10_1053.ply", "longdress_vox10_1051.ply"]
    np.testing.assert_array_equal(seq.frames[1].points, voxel_cloud(0).points)
    assert seq.bit_depth == 10 and "8i" in seq.meta["source"]
    monkeypatch.setenv(datasets.DATA_DIR_ENV, str(tmp_path))
    assert len(load_dataset("longdress", frames=3)) == 3
    rows = {r["name"]: r for r in datasets.describe_datasets()}
    assert rows["human"]["available"] and not rows["longdress"]["available"]
    assert "297 of 300" in rows["longdress"]["reason"]
    assert "no loot PLY frames" in rows["loot"]["reason"]


def test_ulliwegner_takes_any_ply_frames(tmp_path):
    for i in (10, 9):
        write_ply(tmp_path / "UlliWegner" / f"ulliwegner_{i}.ply", voxel_cloud(i))
    seq = load_dataset("ulliwegner", data_dir=tmp_path)
    assert [p.name for p in seq.files] == ["ulliwegner_9.ply", "ulliwegner_10.ply"]


def test_user_folder_frames_and_params(tmp_path):
    for i in range(4):
        write_ply(tmp_path / "seq" / f"f_{i}.ply", voxel_cloud(i))
    seq = load_dataset(tmp_path / "seq", frames=2)
    assert seq.name == "seq" and [p.name for p in seq.files] == ["f_0.ply", "f_1.ply"]
    assert len(load_dataset(str(tmp_path / "seq" / "*.ply"))) == 4
    with pytest.raises(UserError, match="has 4 frames"):
        load_dataset(tmp_path / "seq", frames=[7])
    with pytest.raises(UserError, match="unknown parameter.*size of PLY frames; they take only voxel_size"):
        load_dataset(tmp_path / "seq", size="tiny")


def test_real_capture_reads(shared_dir):
    punching = load_dataset(shared_dir / "data" / "dfaust_50004_punching", frames=[0, 16])
    assert len(punching) == 2 and punching.bit_depth is None
    assert [p.name for p in punching.files] == sorted(p.name for p in punching.files)
    assert punching.files[1] == sorted((shared_dir / "data" / "dfaust_50004_punching").glob("*.ply"))[16]


def test_cli_value_parsing():
    assert parse_params(["size=tiny", "bit_depth=9", "fps=24.5", "height=none", "cache=false"]) == {
        "size": "tiny", "bit_depth": 9, "fps": 24.5, "height": None, "cache": False}
    with pytest.raises(UserError, match="KEY=VALUE"):
        parse_params(["size"])
    assert parse_frames("5") == 5
    assert parse_frames("0,3-5,9") == [0, 3, 4, 5, 9]
    assert parse_frames(None) is None
    with pytest.raises(UserError, match="--frames"):
        parse_frames("a,b")


def test_paper_registry_file_names():
    assert datasets.expected_files(PAPER["soldier"])[0] == "soldier_vox10_0536.ply"
    assert datasets.expected_files(PAPER["redandblack"])[-1] == "redandblack_vox10_1749.ply"
    assert datasets.expected_files(PAPER["loot"])[-1] == "loot_vox10_1299.ply"
    assert len(datasets.expected_files(PAPER["longdress"])) == 300
    assert datasets.expected_files(PAPER["ulliwegner"]) is None
