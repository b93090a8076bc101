"""calibrate -> ingest -> depth on a synthetic, deliberately imperfect array (issue 11): the
registered capture carries masks and geometry, depth gets metric depth and a point cloud, and
its accuracy against the rig's true depth is compared with the same chain on an ideal array."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import require_dataset

from hyperlf.calibration import read_calibration, view_maps
from hyperlf.calibration.rig import make_rig
from hyperlf.cli import main
from hyperlf.formats import load_lightfield, read_pfm, write_image
from hyperlf.formats.ply import read_ply, read_ply_properties

BORDER = 12


def write_shots(folder, images, cols):
    folder.mkdir(parents=True)
    for (r, c), img in images.items():
        write_image(folder / f"Cam-{r * cols + c}.png", np.clip(img, 0, 1), bit_depth=16)
    return folder


def chain(tmp, rig, labels=32, focal=300.0, poses=1, depth_args=()):
    """calibrate (one board pose: plane registration; several: full calibration) -> ingest
    (the scene) -> depth; the metric depth map (None when the capture has no trustworthy
    metric geometry)."""
    R, C = rig.grid
    if poses == 1:
        board = write_shots(tmp / "board", rig.render(rig.board_pose(450.0), supersample=2), C)
    else:
        board = tmp / "board"
        for i, pose in enumerate(rig.calibration_poses(poses)):
            write_shots(board / f"pose{i:02d}", rig.render(pose, supersample=2), C)
    scene = write_shots(tmp / "scene", rig.render(None, supersample=2), C)
    b = f"{rig.board.cols},{rig.board.rows}"
    assert main(["-q", "calibrate", str(board), "--pattern", "Cam-{index}.png", "--grid",
                 f"{R},{C}", "--board", b, "--square", str(rig.board.square),
                 *(["--focal-px", str(focal)] if focal else []), "-o", str(tmp / "cal")]) == 0
    assert main(["-q", "ingest", str(scene), "--calibration", str(tmp / "cal"), "--pattern",
                 "Cam-{index}.png", "-o", str(tmp / "cap")]) == 0
    assert main(["-q", "depth", str(tmp / "cap"), "--labels", str(labels), *depth_args,
                 "-o", str(tmp / "depth")]) == 0
    metric = tmp / "depth" / "depth.pfm"
    return read_pfm(metric) if metric.exists() else None


def truth_in_output_frame(tmp, rig):
    """The rig's true depth of the reference camera, seen in the registered / rectified frame.

    Full mode: rectification turns the reference camera (the rig's 1-2 degrees), and hyperlf's
    depth (``f B / d``) is measured along the rectified optical axis; a point's depth along the
    raw axis differs by up to ``tan(field angle) sin(rotation)``, about 2 % at this rig's image
    edges. The true raw depth is carried over along the pixel's ray: a rotation keeps the
    distance to the camera centre, so ``Z_rect |K_rect^-1 (x, y, 1)| = Z_raw |(u, v, 1)|`` with
    ``(u, v)`` the raw pixel's true undistorted coordinates."""
    import cv2

    cal = read_calibration(tmp / "cal" / "calibration.toml")
    mx, my = view_maps(cal, cal.reference)
    raw = rig.depth(cal.reference)
    H, W = raw.shape
    xi, yi = np.rint(mx).astype(int), np.rint(my).astype(int)
    inside = (xi >= 0) & (xi < W) & (yi >= 0) & (yi < H)
    Z = np.where(inside, raw[np.clip(yi, 0, H - 1), np.clip(xi, 0, W - 1)], np.nan)
    if cal.mode != "full":  # plane mode keeps the reference camera's own axis
        return Z
    cam = rig.cameras[cal.reference]
    pts = np.stack([mx.ravel(), my.ravel()], -1).astype(np.float64).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 60, 1e-12)
    uv = cv2.undistortPoints(pts, cam.K, cam.dist, None, None, None, crit).reshape(*mx.shape, 2)
    yy, xx = np.mgrid[0:mx.shape[0], 0:mx.shape[1]].astype(np.float64)
    rect = np.stack([xx, yy, np.ones_like(xx)], -1) @ np.linalg.inv(cal.camera_matrix).T
    rect /= rect[..., 2:]
    return Z * np.sqrt(1.0 + (uv ** 2).sum(-1)) / np.linalg.norm(rect, axis=-1)


def away_from_depth_edges(truth, radius=2, jump=0.05):
    """Pixels whose ``(2 radius + 1)^2`` neighbourhood of true depth varies by less than
    ``jump`` (relative): calibration is judged there; depth edges are issue 12's subject, and
    the true depth sampled into a rotated frame is only nearest-pixel accurate at them."""
    from scipy import ndimage

    t = np.nan_to_num(truth, nan=0.0)
    size = 2 * radius + 1
    spread = ndimage.maximum_filter(t, size) - ndimage.minimum_filter(t, size)
    return spread < jump * np.maximum(t, 1e-9)


def depth_rmse(Z, truth, valid):
    """RMSE of depth and the fraction of pixels it covers; the relative RMSE too."""
    keep = valid & away_from_depth_edges(truth)
    keep[:BORDER], keep[-BORDER:], keep[:, :BORDER], keep[:, -BORDER:] = False, False, False, False
    keep &= np.isfinite(Z) & np.isfinite(truth)
    err = Z[keep] - truth[keep]
    return (float(np.sqrt(np.mean(err ** 2))), float(keep.mean()),
            float(np.sqrt(np.mean((err / truth[keep]) ** 2))))


def run_chains(tmp_path_factory, **kw):
    out = {}
    for name, imperfect in (("ideal", 0.0), ("imperfect", 1.0)):
        rig = make_rig(2, 3, seed=21, imperfect=imperfect)
        tmp = tmp_path_factory.mktemp(name)
        Z = chain(tmp, rig, **kw)
        out[name] = dict(tmp=tmp, rig=rig, Z=Z, truth=truth_in_output_frame(tmp, rig),
                         lf=load_lightfield(tmp / "cap"))
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Plane registration (one board pose) of an ideal and an imperfect 2 x 3 array."""
    return run_chains(tmp_path_factory)


@pytest.fixture(scope="module")
def full_runs(tmp_path_factory):
    """Full calibration (10 poses) of the same arrays; rectified, so d = f B / Z > 0; no
    disparity range given anywhere."""
    return run_chains(tmp_path_factory, poses=10)  # the range: measured at ingest


def test_ingested_capture_has_masks_geometry_and_measured_positions(runs):
    lf, rig = runs["imperfect"]["lf"], runs["imperfect"]["rig"]
    assert lf.valid is not None and lf.valid.shape == lf.views.shape
    assert lf.valid[lf.reference].mean() > 0.95 and lf.valid.mean() < 1.0
    assert {"camera_matrix", "baseline", "board_plane"} <= set(lf.metadata["calibration"])
    true = rig.true_positions()
    got = lf.positions - lf.positions[lf.reference]
    for k in true:
        want = np.asarray(true[k]) - np.asarray(true[lf.reference])
        assert np.linalg.norm(got[k] - want) < 0.1, (k, got[k], want)


def test_depth_writes_metric_depth_and_a_point_cloud(runs):
    tmp = runs["imperfect"]["tmp"]
    pts, rgb = read_ply(tmp / "depth" / "points.ply")
    Z = runs["imperfect"]["Z"]
    assert len(pts) == np.isfinite(Z).sum() and rgb.shape == pts.shape
    np.testing.assert_allclose(np.sort(pts[:, 2]), np.sort(Z[np.isfinite(Z)]), rtol=1e-5)
    assert (tmp / "depth" / "depth.png").is_file()


def test_min_confidence_leaves_the_unsure_pixels_out_of_the_metric_outputs(runs, tmp_path):
    """``depth --min-confidence C``: the same estimate; the metric outputs keep exactly the
    pixels whose confidence (a PLY property of every point either way) is at least C."""
    tmp = runs["imperfect"]["tmp"]
    every = read_ply_properties(tmp / "depth" / "points.ply")
    Z = read_pfm(tmp / "depth" / "depth.pfm")
    conf = every["confidence"]
    assert len(conf) == np.isfinite(Z).sum() and conf.min() >= 0 and conf.max() <= 1
    conf_map = read_pfm(tmp / "depth" / "confidence.pfm")  # the exact map, beside the picture
    np.testing.assert_array_equal(conf, conf_map[np.isfinite(Z)])
    c = float(np.median(conf))
    assert 0 < c < 1
    assert main(["-q", "depth", str(tmp / "cap"), "--labels", "32", "--min-confidence", str(c),
                 "-o", str(tmp_path / "d")]) == 0
    np.testing.assert_array_equal(read_pfm(tmp_path / "d" / "disparity.pfm"),
                                  read_pfm(tmp / "depth" / "disparity.pfm"))
    kept = read_ply_properties(tmp_path / "d" / "points.ply")
    sure = conf >= np.float32(c)
    assert 0.3 < sure.mean() < 0.95
    for name in ("x", "y", "z", "red", "confidence"):
        np.testing.assert_array_equal(kept[name], every[name][sure])
    want = np.where(conf_map >= np.float32(c), Z, np.nan)
    np.testing.assert_array_equal(read_pfm(tmp_path / "d" / "depth.pfm"), want)


def test_depth_at_half_resolution_keeps_the_metric_depth(runs, capsys):
    """``depth --downscale 2``: maps of half the size, disparities in their own px, and the
    same metric depth as the full-resolution run (the camera matrix follows the blocks)."""
    from hyperlf.imageops import block_reduce

    run = runs["ideal"]
    tmp, full = run["tmp"], run["Z"]
    assert main(["depth", str(tmp / "cap"), "--labels", "32", "--downscale", "2",
                 "-o", str(tmp / "half")]) == 0
    assert "1/2 resolution" in capsys.readouterr().err
    d_full = read_pfm(tmp / "depth" / "disparity.pfm")
    d_half = read_pfm(tmp / "half" / "disparity.pfm")
    Z = read_pfm(tmp / "half" / "depth.pfm")
    H, W = full.shape
    assert Z.shape == d_half.shape == (-(-H // 2), -(-W // 2))
    keep = np.isfinite(Z) & np.isfinite(block_reduce(full, 2))
    keep &= block_reduce(away_from_depth_edges(run["truth"]).astype(float), 2) == 1
    keep[:BORDER // 2], keep[-BORDER // 2:], keep[:, :BORDER // 2], keep[:, -BORDER // 2:] = (
        False, False, False, False)
    assert keep.mean() > 0.5
    ratio = Z[keep] / block_reduce(full, 2)[keep]
    assert abs(np.median(ratio) - 1) < 0.01 and np.percentile(np.abs(ratio - 1), 90) < 0.05
    step = np.median(np.abs(d_half[keep] - block_reduce(d_full, 2)[keep] / 2))
    assert step < 0.25, step  # half-resolution px


def test_downscale_too_far_is_refused_before_any_work(runs, tmp_path, capsys):
    tmp = runs["ideal"]["tmp"]
    H, W = runs["ideal"]["Z"].shape
    n = min(H, W) // 16 + 1
    assert main(["depth", str(tmp / "cap"), "--downscale", str(n), "-o", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--downscale {n} leaves" in err[0] and "use at most" in err[0]
    assert not (tmp_path / "d").exists()


def depth_scores(runs):
    scores = {}
    for name, run in runs.items():
        valid = run["lf"].valid[run["lf"].reference]
        scores[name] = depth_rmse(run["Z"], run["truth"], valid)
    return scores


@pytest.mark.slow
def test_full_calibration_depth_is_near_the_ideal_array(full_runs):
    """Judged target: depth after calibrate + ingest within 10 % of the RMSE the same chain
    reaches on an ideal array (lens distortion, rotations, focal and gain differences all
    corrected by the full calibration)."""
    for run in full_runs.values():  # measured on the rectified scene at ingest: d = f B / Z
        lo, hi = run["lf"].disparity_range
        fB = np.asarray(run["lf"].metadata["calibration"]["camera_matrix"])[0, 0] * \
            run["lf"].metadata["calibration"]["baseline"]
        true_d = fB / run["truth"][np.isfinite(run["truth"])]
        assert lo <= 0 and true_d.max() < hi < 1.6 * true_d.max(), (lo, hi, true_d.max())
    scores = depth_scores(full_runs)
    (ideal, cov_i, rel_i), (imperfect, cov, rel) = scores["ideal"], scores["imperfect"]
    assert rel_i < 0.02 and rel < 0.10, scores  # depth within 10 % (RMSE) on both arrays
    assert cov > 0.9 * cov_i, scores
    # the stricter reading: RMSE within 1.10 x the ideal array's (measured 0.91 x)
    assert imperfect <= 1.10 * ideal, scores


def test_plane_registration_depth_is_sane(runs):
    """One board pose cannot undo lens distortion (a homography per view), so the imperfect
    array is not held to the ideal one's accuracy here; both must still give depth of the
    right scale over most of the view."""
    scores = depth_scores(runs)
    for name, (rmse, cov, rel) in scores.items():
        assert rel < 0.25 and cov > 0.75, (name, scores)


def test_a_square_on_board_leaves_the_focal_length_open(tmp_path, capsys):
    """An ideal array facing the board squarely: registration works, the focal length (and so
    metric depth) is not determined; calibrate says so and depth writes no metric outputs."""
    rig = make_rig(1, 3, seed=4, imperfect=0.0)
    assert chain(tmp_path, rig, labels=8, focal=None,
                 depth_args=("--disparity-range=-8,8",)) is None
    capsys.readouterr()
    assert main(["calibrate", str(tmp_path / "board"), "--pattern", "Cam-{index}.png",
                 "--grid", "1,3", "--board", f"{rig.board.cols},{rig.board.rows}",
                 "-o", str(tmp_path / "cal2")]) == 0
    assert "--focal-px" in capsys.readouterr().err  # the note, without -q
    lf = load_lightfield(tmp_path / "cap")
    assert lf.metadata["calibration"]["focal_determined"] is False
    assert (tmp_path / "depth" / "disparity.pfm").is_file()
    assert not (tmp_path / "depth" / "points.ply").exists()


def _gradient_ncc(a, b, keep):
    """Normalised correlation of two images' gradient magnitudes over ``keep`` (bands differ
    in brightness and contrast, their edges lie in the same places when registered)."""
    import cv2

    def g(x):
        x = np.asarray(x, np.float64)
        return np.hypot(cv2.Sobel(x, cv2.CV_64F, 1, 0), cv2.Sobel(x, cv2.CV_64F, 0, 1))

    u, v = g(a)[keep], g(b)[keep]
    u, v = u - u.mean(), v - v.mean()
    return float((u * v).sum() / np.sqrt((u * u).sum() * (v * v).sum()))


def test_the_lab_capture_without_wavelengths_is_completed(tmp_path, capsys, monkeypatch):
    """The real 3 x 3 lab capture (filter wavelengths not published) from its folders to a
    cube with the documented commands: every camera's band registered onto the reference.
    Measured (1/8 resolution): the gradients of the completed bands correlate with the
    reference's at 0.64-0.97, those of the ingested views (registered at the board plane
    only) at 0.20-0.53."""
    from hyperlf.completion import read_band_mask
    from hyperlf.formats import open_cube_h5
    from hyperlf.lightfield import downscale

    lab = require_dataset("real_arrays/msir_lab")
    pattern = ["--pattern", "Cam-{index}.png"]
    assert main(["-q", "calibrate", str(lab / "calibration"), *pattern, "--grid", "3,3",
                 "--board", "11,8", "-o", str(tmp_path / "cal")]) == 0
    assert main(["-q", "ingest", str(lab / "scene"), "--calibration", str(tmp_path / "cal"),
                 *pattern, "-o", str(tmp_path / "cap")]) == 0
    capsys.readouterr()
    from hyperlf import cli
    monkeypatch.setattr(cli, "_bars", lambda args: not args.quiet)  # as on a terminal
    assert main(["complete", str(tmp_path / "cap"), "--downscale", "8",
                 "-o", str(tmp_path / "cube")]) == 0
    err = capsys.readouterr().err
    assert "no wavelengths" in err
    # every long stage shows progress (the bars are left behind in the captured stream)
    for stage in ("pairwise stereo", "refinement (WLS)", "registration", "propagation, pass 1",
                  "inference and output"):
        assert stage in err, stage
    assert (tmp_path / "cube" / "reference_bands.png").is_file()
    assert not (tmp_path / "cube" / "reference_srgb.png").exists()
    lf = downscale(load_lightfield(tmp_path / "cap"), 8)
    ref = lf.reference
    with open_cube_h5(tmp_path / "cube" / "cube.h5") as cf:
        assert cf.cube.shape == (3, 3, 9) + lf.image_shape
        assert np.isnan(cf.wavelengths).all()
        bands = np.asarray(cf.cube[ref])
    registered = read_band_mask(tmp_path / "cube" / "cube.h5", view=ref)
    own = lf.valid[ref]  # the reference's own band (invalid pixels: filled from neighbours)
    assert own.mean() > 0.99
    np.testing.assert_array_equal(bands[ref[0] * 3 + ref[1]][own], lf.views[ref][own])
    for k, view in enumerate(np.ndindex(3, 3)):
        if view == ref:
            continue
        keep = registered[k] & lf.valid[view] & lf.valid[ref]
        assert keep.mean() > 0.5, (view, keep.mean())
        done = _gradient_ncc(lf.views[ref], bands[k], keep)
        raw = _gradient_ncc(lf.views[ref], lf.views[view], keep)
        assert done > 0.55 and done > raw + 0.25, (view, done, raw)
