import numpy as np
import pytest

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.plyio import PointCloud, read_ply, write_ply
from dpcbench.bench.data.sequences import list_frame_files, load_sequence, natural_key


def test_natural_order(tmp_path):
    names = ["x_10.ply", "x_9.ply", "x_1.ply", "frame0002.ply", "frame0001.ply"]
    for n in names:
        write_ply(tmp_path / n, np.zeros((1, 3)))
    got = [p.name for p in list_frame_files(tmp_path)]
    assert got == ["frame0001.ply", "frame0002.ply", "x_1.ply", "x_9.ply", "x_10.ply"]
    assert sorted(["longdress_vox10_1100.ply", "longdress_vox10_1051.ply"], key=natural_key)[0].endswith("1051.ply")


@pytest.mark.parametrize("ascii", [False, True])
@pytest.mark.parametrize("with_colors", [False, True])
@pytest.mark.parametrize("with_normals", [False, True])
def test_round_trip(tmp_path, ascii, with_colors, with_normals):
    rng = np.random.default_rng(0)
    pts = rng.integers(0, 1024, size=(500, 3)).astype(np.float64)
    cols = rng.integers(0, 256, size=(500, 3)).astype(np.uint8) if with_colors else None
    nrm = rng.normal(size=(500, 3)).astype(np.float32).astype(np.float64) if with_normals else None
    path = write_ply(tmp_path / "f.ply", PointCloud(pts, cols, nrm), ascii=ascii)
    back = read_ply(path)
    np.testing.assert_array_equal(back.points, pts)
    if with_colors:
        np.testing.assert_array_equal(back.colors, cols)
    else:
        assert back.colors is None
    if with_normals:
        np.testing.assert_allclose(back.normals, nrm, rtol=1e-6)
    else:
        assert back.normals is None


def test_corrupt_and_truncated(tmp_path):
    good = write_ply(tmp_path / "good.ply", np.arange(300, dtype=float).reshape(100, 3))
    data = good.read_bytes()
    (tmp_path / "trunc.ply").write_bytes(data[: len(data) - 100])
    with pytest.raises(UserError, match="trunc.ply"):
        read_ply(tmp_path / "trunc.ply")
    (tmp_path / "junk.ply").write_bytes(b"this is not a ply file\n")
    with pytest.raises(UserError, match="junk.ply"):
        read_ply(tmp_path / "junk.ply")


def test_empty_and_nan_frames(tmp_path):
    write_ply(tmp_path / "empty.ply", np.zeros((0, 3)))
    with pytest.raises(UserError, match="zero points"):
        read_ply(tmp_path / "empty.ply")
    pts = np.ones((10, 3))
    pts[3, 1] = np.nan
    write_ply(tmp_path / "nan.ply", pts)
    with pytest.raises(UserError, match="NaN"):
        read_ply(tmp_path / "nan.ply")


def test_mismatched_attributes(tmp_path):
    write_ply(tmp_path / "a_1.ply", PointCloud(np.ones((5, 3)), np.zeros((5, 3), np.uint8)))
    write_ply(tmp_path / "a_2.ply", PointCloud(np.ones((5, 3))))
    with pytest.raises(UserError, match="mismatched attributes"):
        load_sequence(tmp_path)


def test_missing_inputs(tmp_path):
    with pytest.raises(UserError, match="no such file or folder"):
        load_sequence(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(UserError, match="no .ply"):
        load_sequence(tmp_path / "empty")


def test_reads_shared_real_data(shared_dir):
    ricardo = load_sequence(shared_dir / "data" / "mvub_ricardo9")
    assert len(ricardo) == 2 and ricardo.frames[0].colors is not None
    assert len(ricardo.frames[0]) > 200_000
    punch = load_sequence(shared_dir / "data" / "dfaust_50004_punching")
    assert len(punch) == 17 and all(len(f) == 100_000 for f in punch.frames)
    assert punch.files[0].name.endswith("0000.ply") and punch.files[-1].name.endswith("0016.ply")


def test_compact_reading_keeps_the_values_in_narrow_types(tmp_path):
    """compact=True: voxelized coordinates as int16, other float32 coordinates and normals as float32;
    every value equal to the float64 reading."""
    rng = np.random.default_rng(0)
    voxels = rng.integers(-1000, 30000, (500, 3)).astype(float)
    normals = rng.normal(size=(500, 3))
    cases = {"vox": voxels, "float": voxels + 0.25, "wide": voxels * 4}  # 4 x 30000 is beyond int16
    for name, points in cases.items():
        write_ply(tmp_path / f"{name}.ply", PointCloud(points, None, normals))
        plain = read_ply(tmp_path / f"{name}.ply")
        compact = read_ply(tmp_path / f"{name}.ply", compact=True)
        assert compact.points.dtype == (np.int16 if name == "vox" else np.float32)
        assert compact.normals.dtype == np.float32
        assert np.array_equal(compact.points.astype(np.float64), plain.points)
        assert np.array_equal(compact.normals.astype(np.float64), plain.normals)
