"""Single real frames of the paper's sequences (issue 50, item 4): `bench.data.sources.paper.find_single_frame`."""

from __future__ import annotations

from pathlib import Path

from dpcbench.bench.data.datasets import PAPER
from dpcbench.bench.data.sources.paper import find_single_frame, single_frame_rows
from dpcbench.bench.reporting.paper import PAPER_SEQUENCES


def touch(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"ply\n")
    return path


def test_the_shared_layout_and_the_usual_layout_with_one_file_are_single_frames(tmp_path):
    one = touch(tmp_path / "8i_longdress_1300" / "longdress_vox10_1300.ply")
    usual = touch(tmp_path / "Loot" / "Ply" / "loot_vox10_1000.ply")
    assert find_single_frame(PAPER["longdress"], tmp_path) == one
    assert find_single_frame(PAPER["loot"], tmp_path) == usual
    # the folder itself given as the data folder
    assert find_single_frame(PAPER["longdress"], one.parent) == one
    assert find_single_frame(PAPER["soldier"], tmp_path) is None
    rows = single_frame_rows(PAPER, tmp_path, PAPER_SEQUENCES)
    assert rows == {"longdress": {"path": str(one), "label": "Longdress, one real frame"},
                    "loot": {"path": str(usual), "label": "Loot, one real frame"}}
    assert list(rows) == ["longdress", "loot"]  # the paper's order


def test_two_frames_are_a_sequence_and_other_files_are_not_frames_of_it(tmp_path):
    touch(tmp_path / "longdress" / "Ply" / "longdress_vox10_1051.ply")
    touch(tmp_path / "longdress" / "Ply" / "longdress_vox10_1052.ply")
    assert find_single_frame(PAPER["longdress"], tmp_path) is None
    # a folder named after the sequence holding another sequence's file is not a frame of it
    touch(tmp_path / "8i_redandblack_x" / "loot_vox10_1000.ply")
    assert find_single_frame(PAPER["redandblack"], tmp_path) is None
    assert single_frame_rows(PAPER, tmp_path / "missing", PAPER_SEQUENCES) == {}


SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def test_the_shared_longdress_frame_is_found_and_its_entry_loads_as_one_frame():
    import pytest

    from dpcbench.bench.data.datasets import load_dataset

    if not (SHARED / "8i_longdress_1300").is_dir():
        pytest.skip("../shared/data/8i_longdress_1300 is not here")
    rows = single_frame_rows(PAPER, SHARED, PAPER_SEQUENCES)
    assert list(rows) == ["longdress"] and rows["longdress"]["label"] == "Longdress, one real frame"
    seq = load_dataset(rows["longdress"]["path"], progress=False)
    assert len(seq) == 1 and len(seq.points[0]) == 857_966


def test_reproduce_paper_protocol_adds_a_row_per_single_real_frame(tmp_path):
    from dpcbench.bench.reporting.paper import TABLE_COLUMNS, paper_protocol

    one = touch(tmp_path / "8i_longdress_1300" / "longdress_vox10_1300.ply")
    protocol = paper_protocol(True, tmp_path)
    assert not protocol.standins
    rows = {s.sequence_label for s in protocol.synthetic}
    assert "Longdress, one real frame" in rows
    longdress = [s for s in protocol.synthetic if s.sequence_label == "Longdress, one real frame"]
    # every column of the tables runs on it (the temporal ones reduce to their per-frame part on one frame)
    assert {(s.method["name"], str(s.method.get("params") or {})) for s in longdress} == {
        (name, str(params)) for name, _, params, _ in TABLE_COLUMNS}
    assert all(str(one) in str(s.sequence) for s in longdress)
    assert {s.sequence_label for s in protocol.real} == {"Longdress, one real frame"}
