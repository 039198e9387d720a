"""Reading user files: a crafted header cannot make the reader decode or allocate a giant image, and a file that is
no depth array says so (not numpy's advice to unpickle it)."""

import struct
import zlib

import numpy as np
import pytest

from ancsh.data.images import MAX_IMAGE_PIXELS, read_depth, read_mask


def _png_header_only(width: int, height: int) -> bytes:
    """A 16-bit grey PNG whose header claims ``width x height`` pixels, with (almost) no pixel data."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 10)) + chunk(b"IEND", b"")


@pytest.mark.parametrize("size", [(20000, 20000), (9000, 9000)])  # beyond PIL's own limit, and between the two
def test_a_png_claiming_a_giant_size_is_refused_from_its_header(tmp_path, size):
    path = tmp_path / "bomb.png"
    path.write_bytes(_png_header_only(*size))
    with pytest.raises(ValueError, match=r"depth: .*bomb.png claims .*pixels.*not read"):
        read_depth(path)


def test_an_npy_claiming_a_giant_shape_is_refused_before_allocating(tmp_path):
    path = tmp_path / "huge.npy"
    with open(path, "wb") as f:  # 100000 x 100000 float64 would be 74 GiB
        np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": (100000, 100000)})
        f.write(b"\0" * 64)
    with pytest.raises(ValueError, match=r"claims an array of shape \(100000, 100000\).*not read"):
        read_depth(path)
    assert 100000 * 100000 > MAX_IMAGE_PIXELS


def test_a_file_that_is_no_array_says_so(tmp_path):
    garbage = tmp_path / "garbage.npy"
    garbage.write_bytes(b"not an array at all")
    with pytest.raises(ValueError, match="garbage.npy is not a depth array"):
        read_depth(garbage)
    objects = tmp_path / "objects.npy"
    np.save(objects, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(ValueError, match="objects.npy is not a depth array") as exc:
        read_depth(objects)
    assert "pickle" not in str(exc.value)
    with pytest.raises(ValueError, match="objects.npy is not a mask array"):
        read_mask(objects, (1,))


def test_ordinary_arrays_still_read(tmp_path):
    np.save(tmp_path / "d.npy", np.full((6, 8), 1.5))
    np.save(tmp_path / "m.npy", np.eye(3, dtype=bool))
    assert read_depth(tmp_path / "d.npy").shape == (6, 8)
    assert read_mask(tmp_path / "m.npy", (3, 3)).sum() == 3


def test_a_depth_of_another_size_than_the_intrinsics_is_refused_from_its_header(tmp_path):
    png = tmp_path / "d.png"
    png.write_bytes(_png_header_only(641, 480))  # no pixel data to decode: the header alone decides
    with pytest.raises(ValueError, match=r"depth: .*d.png is 641x480 pixels, the intrinsics say 640x480.*not read"):
        read_depth(png, shape=(480, 640))
    npy = tmp_path / "d.npy"
    with open(npy, "wb") as f:  # a header without its data
        np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": (48, 64)})
    with pytest.raises(ValueError, match=r"d.npy is 64x48 pixels, the intrinsics say 640x480"):
        read_depth(npy, shape=(480, 640))
    np.save(npy, np.full((48, 64), 1.5))
    assert read_depth(npy, shape=(48, 64)).shape == (48, 64)


def test_mask_bounds_are_the_rows_and_columns_of_its_pixels():
    from ancsh.data.images import mask_bounds

    rng = np.random.default_rng(4)
    for _ in range(20):
        m = np.zeros((37, 53), dtype=bool)
        m[tuple(rng.integers(0, (37, 53), size=(int(rng.integers(1, 30)), 2)).T)] = True
        v, u = np.nonzero(m)
        assert mask_bounds(m) == (v.min(), v.max() + 1, u.min(), u.max() + 1)
    assert mask_bounds(np.zeros((5, 5), dtype=bool)) is None
    with pytest.raises(ValueError, match="mask"):
        mask_bounds(np.zeros(5, dtype=bool))
