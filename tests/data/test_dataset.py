"""HDF5 shards: round trip, ground-truth consistency, damaged files, bulk reading."""

import numpy as np
import pytest

from ancsh.data.dataset import (
    FIELDS,
    CorruptShardError,
    FrameDataset,
    ShardReader,
    frame_record,
    read_arrays,
    read_frames,
    write_shard,
)
from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.data.noise import DepthNoise
from ancsh.data.render import Intrinsics

SMALL = Intrinsics.kinect(160, 120)
FLOAT32_KEYS = {k for k, (dtype, _) in FIELDS.items() if dtype == "f4"}


@pytest.fixture(scope="module")
def frames():
    """Four noise-free drawer frames (4 parts, 3 prismatic joints) and two noisy laptop frames."""
    drawer = FrameGenerator(GenerationConfig(category="drawer", intrinsics=SMALL, num_points=128, noise=DepthNoise.off(),
                                             min_part_pixels=5))
    laptop = FrameGenerator(GenerationConfig(category="laptop", intrinsics=SMALL, num_points=128, min_part_pixels=5))
    return [drawer.frame(i) for i in range(4)], [laptop.frame(i) for i in range(2)]


def _write(path, frs, start=0):
    return write_shard(path, frs, split="train", source="procedural", config="{}", frame_start=start)


def test_shard_round_trip_keeps_every_field(tmp_path, frames):
    drawer, _ = frames
    path = _write(tmp_path / "d.h5", drawer)
    reader = ShardReader(path)
    assert len(reader) == 4 and reader.category == "drawer"
    assert reader.part_names == drawer[0].part_names and reader.joint_names == drawer[0].joint_names
    for original, back in zip(drawer, reader):
        a, b = frame_record(original), frame_record(back)
        assert set(a) == set(FIELDS)
        for key in FIELDS:
            if key in FLOAT32_KEYS:
                np.testing.assert_allclose(b[key], a[key], rtol=1e-6, atol=1e-6, err_msg=key)
            elif FIELDS[key][0] == "str":
                assert a[key] == b[key]
            else:
                np.testing.assert_array_equal(b[key], a[key], err_msg=key)
        assert back.gt.joint_types == original.gt.joint_types
        assert back.intrinsics == original.intrinsics and back.seed == original.seed
        assert back.instance == original.instance and back.frame_index == original.frame_index


def test_stored_ground_truth_is_consistent(tmp_path, frames):
    """NPCS mapped by the stored part pose gives the stored points; NAOCS = s NPCS + t;
    the amodal boxes hold their parts' points; camera joints follow from NAOCS joints."""
    drawer, laptop = frames
    associated = 0
    for frs, name in ((drawer, "d.h5"), (laptop, "l.h5")):
        for fr in ShardReader(_write(tmp_path / name, frs)):
            gt = fr.gt
            for j in range(fr.num_parts):
                sel = gt.part_labels == j
                assert sel.any()
                np.testing.assert_allclose(gt.T_cam_npcs[j].apply(gt.npcs[sel]), fr.points[sel], atol=1e-5)
                np.testing.assert_allclose(gt.npcs_scale[j] * gt.npcs[sel] + gt.npcs_translation[j], gt.naocs[sel],
                                           atol=1e-5)
                assert gt.boxes_cam[j].contains(fr.points[sel], tol=2e-2 if fr.category == "laptop" else 1e-5).all()
            for k in range(fr.num_joints):
                for part in (gt.joint_parents[k], gt.joint_children[k]):  # either connected part
                    T = gt.T_cam_naocs_part(int(part))
                    np.testing.assert_allclose(T.apply_direction(gt.joint_axes_naocs[k]), gt.joint_axes_cam[k],
                                               atol=1e-9)
                    if gt.joint_types[k].value == "revolute":
                        np.testing.assert_allclose(T.apply(gt.joint_pivots_naocs[k]), gt.joint_pivots_cam[k], atol=1e-9)
                assoc = gt.joint_association == k + 1
                associated += assoc.sum()
                np.testing.assert_allclose(gt.joint_targets[assoc, :3], np.broadcast_to(gt.joint_axes_naocs[k], (assoc.sum(), 3)),
                                           atol=1e-6)
                if gt.joint_types[k].value == "revolute":  # point + distance * direction lies on the axis
                    foot = gt.naocs[assoc] + gt.joint_targets[assoc, 6:7] * gt.joint_targets[assoc, 3:6]
                    rel = foot - gt.joint_pivots_naocs[k]
                    off_axis = rel - np.outer(rel @ gt.joint_axes_naocs[k], gt.joint_axes_naocs[k])
                    assert np.abs(off_axis).max() < 1e-5
                    assert np.all(gt.joint_targets[assoc, 6] <= 0.2 + 1e-6)
            assert np.all(fr.visibility > 0) and np.all(fr.visibility <= 1)
    assert associated > 0


def test_frame_dataset_spans_shards_and_bulk_arrays(tmp_path, frames):
    drawer, _ = frames
    _write(tmp_path / "a_00000.h5", drawer[:3], 0)
    _write(tmp_path / "a_00001.h5", drawer[3:], 3)
    ds = FrameDataset(tmp_path)
    assert len(ds) == 4
    assert ds[3].frame_index == drawer[3].frame_index and ds[-1].frame_index == drawer[3].frame_index
    with pytest.raises(IndexError):
        ds[4]
    arr = read_arrays(tmp_path, ["points", "part_labels"])
    assert set(arr) == {"points", "part_labels"}
    assert arr["points"].shape == (4, 128, 3) and arr["points"].dtype == np.float32
    np.testing.assert_allclose(arr["points"][3], drawer[3].points, atol=1e-6)
    assert len(read_frames(tmp_path / "a_00001.h5")) == 1
    with pytest.raises(KeyError, match="unknown field"):
        read_arrays(tmp_path, ["colour"])
    (tmp_path / "sub").mkdir()
    with pytest.raises(FileNotFoundError, match="no \\*.h5"):
        FrameDataset(tmp_path / "sub")


def test_writer_rejects_bad_input(tmp_path, frames):
    drawer, laptop = frames
    with pytest.raises(ValueError, match="at least one frame"):
        _write(tmp_path / "x.h5", [])
    with pytest.raises(ValueError, match="frames\\[1\\]"):
        _write(tmp_path / "x.h5", [drawer[0], laptop[0]])
    assert not list(tmp_path.iterdir())  # nothing written, no temporary file left


def test_truncated_shard_is_reported_by_name(tmp_path, frames):
    path = _write(tmp_path / "broken_shard.h5", frames[0])
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(CorruptShardError, match="broken_shard.h5"):
        ShardReader(path)
    (tmp_path / "garbage.h5").write_bytes(b"not an hdf5 file at all")
    with pytest.raises(CorruptShardError, match="garbage.h5"):
        FrameDataset(tmp_path / "garbage.h5")


def test_damaged_chunk_is_caught_by_its_checksum(tmp_path, frames):
    import h5py

    path = _write(tmp_path / "flipped.h5", frames[0])
    with h5py.File(path, "r") as f:
        offset = f["points"].id.get_offset() if f["points"].chunks is None else f["points"].id.get_chunk_info(0).byte_offset
    raw = bytearray(path.read_bytes())
    raw[offset + 100] ^= 0xFF
    path.write_bytes(bytes(raw))
    reader = ShardReader(path)  # attributes are intact
    with pytest.raises(CorruptShardError, match="flipped.h5"):
        reader[0]


def test_reader_errors(tmp_path, frames):
    with pytest.raises(FileNotFoundError, match="no such"):
        ShardReader(tmp_path / "missing.h5")
    reader = ShardReader(_write(tmp_path / "ok.h5", frames[0]))
    with pytest.raises(IndexError):
        reader[10]
    with pytest.raises(TypeError, match="index"):
        reader["0"]


def test_frame_dataset_keeps_few_shards_in_memory(tmp_path, frames):
    drawer, _ = frames
    for s in range(4):
        _write(tmp_path / f"s_{s:05d}.h5", drawer[s : s + 1], s)
    ds = FrameDataset(tmp_path, max_loaded=2)
    seen = [fr.frame_index for fr in ds]
    assert seen == [fr.frame_index for fr in drawer]
    assert sum(r._data is not None for r in ds.readers) == 2
    with pytest.raises(ValueError, match="max_loaded"):
        FrameDataset(tmp_path, max_loaded=0)
