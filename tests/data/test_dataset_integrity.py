"""Dataset bytes are checksummed and verified on read; one damaged shard does not block the others."""

import numpy as np
import pytest

from ancsh.data.dataset import CorruptShardError, FrameDataset, ShardReader, write_shard
from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.data.noise import DepthNoise
from ancsh.data.render import Intrinsics


@pytest.fixture(scope="module")
def laptop_frames():
    gen = FrameGenerator(GenerationConfig(category="laptop", intrinsics=Intrinsics.kinect(160, 120), num_points=64,
                                          noise=DepthNoise.off(), min_part_pixels=5))
    return [gen.frame(i) for i in range(3)]


def _write(path, frames, start=0):
    return write_shard(path, frames, split="train", source="procedural", config="{}", frame_start=start)


def test_every_single_byte_flip_is_detected_or_harmless(tmp_path, laptop_frames):
    """Flip one byte at 192 offsets spread over the file: each read either fails naming the shard
    or returns exactly the original arrays (never silently different data, e.g. zeros)."""
    path = _write(tmp_path / "good.h5", laptop_frames)
    original = ShardReader(path).arrays()
    raw = path.read_bytes()
    silent = []
    for offset in np.linspace(0, len(raw) - 1, 192).astype(int):
        damaged = bytearray(raw)
        damaged[offset] ^= 0xFF
        flipped = tmp_path / "flipped.h5"
        flipped.write_bytes(bytes(damaged))
        try:
            data = ShardReader(flipped).arrays()
        except CorruptShardError as exc:
            assert "flipped.h5" in str(exc)
            continue
        for key, value in original.items():
            if not np.array_equal(data[key], value, equal_nan=value.dtype != object):
                silent.append((int(offset), key))
    assert not silent, f"damage read back silently at (offset, dataset) {silent[:5]}"


def test_one_bad_shard_does_not_block_the_intact_ones(tmp_path, laptop_frames):
    _write(tmp_path / "a_00000.h5", laptop_frames[:1])
    _write(tmp_path / "a_00001.h5", laptop_frames[1:2], start=1)
    _write(tmp_path / "a_00002.h5", laptop_frames[2:], start=2)
    (tmp_path / "a_00001.h5").write_bytes(b"damaged")
    with pytest.raises(CorruptShardError, match="a_00001.h5"):
        FrameDataset(tmp_path)
    ds = FrameDataset(tmp_path, skip_corrupt=True)
    assert len(ds) == 2 and [p.name for p, _ in ds.skipped] == ["a_00001.h5"]
    assert list(ds.arrays(["frame_index"])["frame_index"]) == [0, 2]
    # data damage found on read: the shard is dropped, the rest stays readable
    raw = bytearray((tmp_path / "a_00002.h5").read_bytes())
    import h5py

    with h5py.File(tmp_path / "a_00002.h5", "r") as f:
        off = f["points"].id.get_chunk_info(0).byte_offset
    raw[off + 10] ^= 0xFF
    (tmp_path / "a_00002.h5").write_bytes(bytes(raw))
    ds = FrameDataset(tmp_path, skip_corrupt=True)
    assert [p.name for p, _ in ds.verify()] == ["a_00001.h5", "a_00002.h5"]
    assert len(ds) == 1 and ds[0].frame_index == 0
