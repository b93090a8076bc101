"""PFM reading/writing: round trips, both byte orders, malformed headers and truncation."""

from __future__ import annotations

import os
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hyperlf.errors import DataNotFoundError, FormatError, InvalidInputError
from hyperlf.formats import read_pfm, write_pfm

FAST = settings(max_examples=60, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.mark.parametrize("scale", [-1.0, 1.0, -2.5])
@pytest.mark.parametrize("shape", [(7, 5), (4, 6, 3), (1, 1)])
def test_round_trip(tmp_path, rng, scale, shape):
    a = rng.normal(size=shape).astype(np.float32)
    a.flat[0] = np.nan
    write_pfm(tmp_path / "a.pfm", a, scale=scale)
    b = read_pfm(tmp_path / "a.pfm")
    assert b.dtype == np.float32 and b.shape == shape
    np.testing.assert_array_equal(a, b)  # NaN positions equal too
    # values are NOT multiplied by |scale|
    assert os.listdir(tmp_path) == ["a.pfm"]


def test_hand_built_big_endian_bottom_up(tmp_path):
    # 3 x 2 image: top row [1, 2, 3], bottom row [4, 5, 6]; stored bottom row first, big-endian
    body = np.array([4, 5, 6, 1, 2, 3], dtype=">f4").tobytes()
    (tmp_path / "be.pfm").write_bytes(b"Pf\n3 2\n1.0\n" + body)
    np.testing.assert_array_equal(read_pfm(tmp_path / "be.pfm"), [[1, 2, 3], [4, 5, 6]])
    # same in little-endian with a single-line header, and CRLF line ends
    body = np.array([4, 5, 6, 1, 2, 3], dtype="<f4").tobytes()
    (tmp_path / "le.pfm").write_bytes(b"Pf 3 2 -1\r\n" + body)
    np.testing.assert_array_equal(read_pfm(tmp_path / "le.pfm"), [[1, 2, 3], [4, 5, 6]])


def test_colour_pfm_big_endian(tmp_path, rng):
    a = rng.random((3, 4, 3)).astype(np.float32)
    write_pfm(tmp_path / "c.pfm", a, scale=1.0)
    assert (tmp_path / "c.pfm").read_bytes().startswith(b"PF\n4 3\n1\n")
    np.testing.assert_array_equal(read_pfm(tmp_path / "c.pfm"), a)


def test_errors(tmp_path):
    with pytest.raises(DataNotFoundError):
        read_pfm(tmp_path / "missing.pfm")
    (tmp_path / "t.pfm").write_bytes(b"Pf\n4 4\n-1\n" + b"\0" * 60)
    with pytest.raises(FormatError, match="truncated"):
        read_pfm(tmp_path / "t.pfm")
    (tmp_path / "z.pfm").write_bytes(b"Pf\n1 1\n0\n" + b"\0" * 4)
    with pytest.raises(FormatError, match="scale"):
        read_pfm(tmp_path / "z.pfm")
    (tmp_path / "p.pfm").write_bytes(b"P6\n1 1\n255\n\0\0\0")
    with pytest.raises(FormatError, match="not a PFM"):
        read_pfm(tmp_path / "p.pfm")
    with pytest.raises(InvalidInputError):
        write_pfm(tmp_path / "bad.pfm", np.zeros((2, 2, 2)))
    with pytest.raises(InvalidInputError):
        write_pfm(tmp_path / "bad.pfm", np.zeros((2, 2)), scale=0)
    assert not (tmp_path / "bad.pfm").exists()


_PFM_ERRORS = ("not a PFM file|malformed PFM header|empty image|PFM scale|is truncated"
               "|bytes more than its header")


@FAST
@given(data=st.one_of(
    st.binary(max_size=64),
    st.builds(lambda head, rest: head + rest, st.sampled_from([b"Pf", b"PF", b"Pf\n1 1\n-1\n"]),
              st.binary(max_size=62))))
def test_garbage_raises_format_error(tmp_path, data):
    """Garbage is refused with a FormatError saying why; only a well-formed file is read."""
    p = tmp_path / "g.pfm"
    p.write_bytes(data)
    if data[:2] not in (b"Pf", b"PF"):
        with pytest.raises(FormatError, match="not a PFM file"):
            read_pfm(p)
        return
    try:
        out = read_pfm(p)
    except FormatError as exc:
        assert re.search(_PFM_ERRORS, str(exc)), str(exc)
        return
    # accepted: the header's shape, and every byte after the header is one float32 value
    assert out.dtype == np.float32
    assert out.ndim == (2 if data[:2] == b"Pf" else 3)
    assert out.size >= 1 and len(data) >= 4 * out.size + 7


@FAST
@given(ident=st.sampled_from([b"Pf", b"PF", b"pf", b"P5"]),
       w=st.integers(0, 5), h=st.integers(0, 5),
       scale=st.sampled_from([b"-1", b"1", b"0", b"nan", b"x", b"-1.0e0", b""]),
       sep=st.sampled_from([b"\n", b" ", b"\t", b""]),
       extra=st.integers(-8, 8))
def test_malformed_headers_and_bodies(tmp_path, ident, w, h, scale, sep, extra):
    ch = 3 if ident == b"PF" else 1
    n = max(0, 4 * w * h * ch + extra)
    p = tmp_path / "m.pfm"
    p.write_bytes(ident + sep + str(w).encode() + b" " + str(h).encode() + sep + scale + b"\n"
                  + b"\x01" * n)
    valid = (ident in (b"Pf", b"PF") and w > 0 and h > 0 and sep != b""
             and scale in (b"-1", b"1", b"-1.0e0") and extra == 0)
    if valid:
        a = read_pfm(p)
        assert a.shape == ((h, w) if ch == 1 else (h, w, 3))
    else:
        with pytest.raises(FormatError):
            read_pfm(p)


def test_interrupted_write_leaves_nothing(tmp_path, monkeypatch):
    import hyperlf.formats.pfm as pfm

    write_pfm(tmp_path / "x.pfm", np.ones((3, 3)))  # an existing file must survive intact

    class HalfWriter:
        """A file that dies after the header, as if the process were killed mid-write."""

        def __init__(self, path, mode):
            self.fh = open(path, mode)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

        def write(self, data):
            if len(data) > 20:
                raise KeyboardInterrupt
            self.fh.write(data)

    monkeypatch.setattr(pfm, "open", HalfWriter, raising=False)
    with pytest.raises(KeyboardInterrupt):
        write_pfm(tmp_path / "x.pfm", np.zeros((3, 3)))
    with pytest.raises(KeyboardInterrupt):
        write_pfm(tmp_path / "new.pfm", np.zeros((3, 3)))
    assert os.listdir(tmp_path) == ["x.pfm"]
    monkeypatch.undo()
    np.testing.assert_array_equal(read_pfm(tmp_path / "x.pfm"), np.ones((3, 3)))
