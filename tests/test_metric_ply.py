"""Metric depth, point clouds and PLY files (issue 11, item 4), against closed-form geometry."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf.calibration.metric import depth_from_disparity, point_cloud
from hyperlf.errors import FormatError, InvalidInputError
from hyperlf.formats.ply import read_ply, read_ply_properties, write_ply

K = [[800.0, 0.0, 20.0], [0.0, 800.0, 15.0], [0.0, 0.0, 1.0]]


def test_rectified_depth_is_f_b_over_d():
    g = {"mode": "full", "camera_matrix": K, "baseline": 40.0}
    Z = np.array([[400.0, 1000.0], [2500.0, 1e4]])
    d = 800.0 * 40.0 / Z
    np.testing.assert_allclose(depth_from_disparity(d, g), Z, rtol=1e-6)
    assert np.isnan(depth_from_disparity(np.array([[0.0, -1.0]]), g)).all()


def test_plane_registered_depth_is_relative_to_a_slanted_board():
    n = np.array([0.1, -0.05, 1.0])
    n /= np.linalg.norm(n)
    g = {"mode": "plane", "camera_matrix": K, "baseline": 40.0,
         "board_plane": [*n, 600.0]}
    H, W = 30, 40
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    rays = np.stack([(xx - 20) / 800, (yy - 15) / 800, np.ones_like(xx)], -1)
    z_board = 600.0 / (rays @ n)
    Z = np.where(xx < 20, 450.0, 900.0)  # a near and a far region
    d = 800.0 * 40.0 * (1 / Z - 1 / z_board)
    np.testing.assert_allclose(depth_from_disparity(d, g), Z, rtol=1e-5)
    on_board = depth_from_disparity(np.zeros((H, W)), g)
    np.testing.assert_allclose(on_board, z_board, rtol=1e-6)


def test_point_cloud_back_projects_through_the_camera_matrix():
    g = {"mode": "full", "camera_matrix": K, "baseline": 40.0}
    Z = np.full((30, 40), 500.0)
    Z[0, 0] = np.nan
    pts, col = point_cloud(Z, g, colours=np.full((30, 40), 0.5))
    assert pts.shape == (30 * 40 - 1, 3) and col.shape == pts.shape
    centre = pts[np.argmin(np.abs(pts[:, 0]) + np.abs(pts[:, 1]))]
    np.testing.assert_allclose(centre, [0.0, 0.0, 500.0], atol=1e-3)
    # pixel (x=39, y=29) -> X = (39 - 20) Z / f
    np.testing.assert_allclose(pts[-1], [19 * 500 / 800, 14 * 500 / 800, 500.0], rtol=1e-5)
    assert (col == 128).all()


@pytest.mark.parametrize("bad", [{}, {"camera_matrix": K}, {"camera_matrix": [[1]], "baseline": 1},
                                 {"camera_matrix": K, "baseline": -1.0},
                                 {"camera_matrix": K, "baseline": 1.0, "board_plane": [1, 2]}])
def test_bad_geometry_is_one_line(bad):
    with pytest.raises(InvalidInputError):
        depth_from_disparity(np.ones((2, 2)), bad)


@settings(max_examples=30, deadline=None)
@given(n=st.integers(0, 50), colour=st.booleans(), seed=st.integers(0, 2**16))
def test_ply_round_trip(tmp_path_factory, n, colour, seed):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)).astype(np.float32)
    col = rng.integers(0, 256, (n, 3)).astype(np.uint8) if colour else None
    p = write_ply(tmp_path_factory.mktemp("ply") / "a.ply", pts, col, comment="unit: mm")
    got, gcol = read_ply(p)
    np.testing.assert_array_equal(got, pts)
    assert (gcol is None) == (col is None)
    if col is not None:
        np.testing.assert_array_equal(gcol, col)


@settings(max_examples=30, deadline=None)
@given(n=st.integers(0, 50), names=st.lists(st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,8}",
                                                          fullmatch=True),
                                            max_size=3, unique=True),
       seed=st.integers(0, 2**16))
def test_ply_scalars_round_trip(tmp_path_factory, n, names, seed):
    names = [m for m in names if m not in ("x", "y", "z", "red", "green", "blue")]
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3))
    scalars = {m: rng.random(n) for m in names}
    p = write_ply(tmp_path_factory.mktemp("ply") / "a.ply", pts,
                  rng.integers(0, 256, (n, 3)).astype(np.uint8), scalars=scalars)
    got = read_ply_properties(p)
    assert list(got) == ["x", "y", "z", "red", "green", "blue", *names]
    for m in names:
        np.testing.assert_array_equal(got[m], scalars[m].astype(np.float32))
    np.testing.assert_array_equal(read_ply(p)[0], pts.astype(np.float32))


@pytest.mark.parametrize("scalars", [{"x": [0.0]}, {"two words": [0.0]}, {"é": [0.0]},
                                     {"1st": [0.0]}, {"c": [0.0, 1.0]}, {"c": [[0.0]]}])
def test_ply_scalars_that_cannot_be_written_are_refused(tmp_path, scalars):
    with pytest.raises(InvalidInputError):
        write_ply(tmp_path / "a.ply", np.zeros((1, 3)), scalars=scalars)
    assert not (tmp_path / "a.ply").exists()


def test_ply_reader_refuses_a_property_named_twice(tmp_path):
    p = tmp_path / "d.ply"
    p.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y"
                  b"\nproperty float z\nproperty float x\nend_header\n1 2 3 4\n")
    with pytest.raises(FormatError, match="twice"):
        read_ply(p)


@settings(max_examples=60, deadline=None)
@given(data=st.binary(max_size=400))
def test_ply_reader_refuses_garbage(tmp_path_factory, data):
    p = tmp_path_factory.mktemp("ply") / "g.ply"
    p.write_bytes(b"ply\n" + data)
    try:
        read_ply(p)
    except FormatError:
        pass


@pytest.mark.parametrize("body", [b"format ascii 1.0\nelement vertex 2\nproperty float x\n"
                                  b"property float y\nproperty float z\nend_header\n1 2\n",
                                  b"format binary_little_endian 1.0\nelement vertex 999999999999"
                                  b"\nproperty float x\nproperty float y\nproperty float z\n"
                                  b"end_header\n\x00\x00"])
def test_ply_reader_refuses_short_data_without_allocating(tmp_path, body):
    p = tmp_path / "s.ply"
    p.write_bytes(b"ply\n" + body)
    with pytest.raises(FormatError):
        read_ply(p)
