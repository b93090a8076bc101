"""Tests of hyperlf.render: sensor emulation, refocusing, all-focus, focal sweeps, spectra."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import ndimage

from hyperlf import render, spectral
from hyperlf.errors import InvalidInputError
from hyperlf.formats.hdf5 import open_cube_h5, write_cube_h5
from hyperlf.synthesis import SCENES, procedural_scene


def _psnr(a, b, peak=1.0):
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(peak ** 2 / mse)


def _lap_var(img, box):
    g = img if img.ndim == 2 else img.mean(axis=-1)
    lap = ndimage.laplace(np.asarray(g, np.float64))
    y0, y1, x0, x1 = box
    return float(lap[y0:y1, x0:x1].var())


@pytest.fixture(scope="module")
def planes():
    """SCENES['planes']: background at -1.5, a plane at 0 and one at +1.5."""
    return procedural_scene(**dict(SCENES["planes"], height=48, width=60))


@pytest.fixture(scope="module")
def integer_scene():
    """Two planes at integer disparities (exact bilinear sampling) with an occlusion."""
    objs = [{"kind": "plane", "disparity": -1.0, "texture": {"pattern": "patches", "period": 0.1}},
            {"kind": "plane", "disparity": 1.0, "rect": [0.3, 0.25, 0.7, 0.75],
             "texture": {"pattern": "patches", "period": 0.12}}]
    return procedural_scene(seed=5, height=40, width=52, objects=objs)


@pytest.fixture(scope="module")
def one_plane():
    """A single infinite fronto-parallel plane at disparity 1."""
    objs = [{"kind": "plane", "disparity": 1.0, "texture": {"pattern": "patches", "period": 0.13}}]
    return procedural_scene(seed=1, height=36, width=44, objects=objs)


# ------------------------------------------------------------------------------ emulation

@pytest.mark.parametrize("output", ["camera", "srgb"])
def test_flat_spectrum_is_grey_for_every_camera(output):
    wl = np.arange(410.0, 701.0, 10.0)
    flat = np.full((wl.size, 3, 4), 0.5, np.float32)
    cams = spectral.list_cameras()  # colour-science's, plus camspec when HYPERLF_DATA is set
    assert "CIE 1931" in cams and len(cams) >= 4
    for cam in cams:
        rgb = render.emulate_camera(flat, wl, cam, output=output, exposure="none")
        assert rgb.shape == (3, 4, 3)
        np.testing.assert_allclose(rgb, rgb[..., :1].repeat(3, -1), atol=2e-5, err_msg=cam)
        if output == "camera":
            np.testing.assert_allclose(rgb, 0.5, atol=2e-5, err_msg=cam)


def test_flat_grey_with_csv_and_array_cameras_and_white(tmp_path):
    wl = np.arange(410.0, 701.0, 10.0)
    S = spectral.camera_sensitivities("Nikon 5100", wl)
    csv = tmp_path / "cam.csv"
    csv.write_text("wavelength_nm,r,g,b\n" + "\n".join(
        f"{w:g},{r:.6g},{g:.6g},{b:.6g}" for w, (r, g, b) in zip(wl, S)))
    flat = np.ones((wl.size, 2, 2))
    for cam in (csv, S):
        for out in ("camera", "srgb"):
            rgb = render.emulate_camera(flat, wl, cam, output=out)
            np.testing.assert_allclose(rgb, 1.0, atol=1e-4)
    # a radiance cube lit by D65 is neutral with white="D65"
    d65 = spectral.illuminant_spd("D65", wl)[:, None, None] * flat
    np.testing.assert_allclose(render.emulate_camera(d65, wl, "Nikon 5100", white="D65"), 1.0,
                               atol=1e-5)
    # without white balance the channels differ
    raw = render.emulate_camera(flat, wl, "Nikon 5100", white_balance=False)
    assert np.ptp(raw[0, 0]) > 0.05 * raw[0, 0].max()


def test_emulated_srgb_matches_independent_cie_rendering(planes):
    wl = planes.cube_wavelengths
    ref = planes.gt_cube[planes.reference]  # (B, H, W)
    spec = np.moveaxis(ref, 0, -1).astype(np.float64)
    # equal-energy white
    got = render.emulate_camera(ref, wl, "CIE 1931", output="srgb", exposure="none")
    white_xy = tuple(spectral.xyz_to_xy(spectral.spectrum_to_xyz(np.ones(wl.size), wl)))
    want = spectral.xyz_to_srgb(spectral.spectrum_to_xyz(spec, wl), white=white_xy, clip=True)
    assert got.shape == want.shape == ref.shape[1:] + (3,)
    np.testing.assert_allclose(got, want, atol=1e-4)
    # D65 white: XYZ relative to D65's Y, adapted from D65's chromaticity (= no adaptation)
    got = render.emulate_camera(ref, wl, "CIE 1931", output="srgb", exposure="none", white="D65")
    d65 = spectral.illuminant_spd("D65", wl)
    wxyz = spectral.spectrum_to_xyz(d65, wl, normalise=None)
    xyz = spectral.spectrum_to_xyz(spec, wl, normalise=None) / wxyz[1]
    want = spectral.xyz_to_srgb(xyz, white=tuple(spectral.xyz_to_xy(wxyz)), clip=True)
    np.testing.assert_allclose(got, want, atol=1e-4)
    # camera output for CIE 1931 is white-balanced XYZ, linear in the cube
    xyz_wb = render.emulate_camera(ref, wl, "CIE 1931")
    S = spectral.cmfs(wl)
    np.testing.assert_allclose(xyz_wb, spec @ (S / S.sum(0)), rtol=1e-4, atol=1e-5)


def test_ccm_makes_rgb_cameras_comparable_to_srgb(planes):
    wl = planes.cube_wavelengths
    ref = planes.gt_cube[planes.reference]
    cie = render.emulate_camera(ref, wl, "CIE 1931", output="srgb", white="D65")
    fitted = render.emulate_camera(ref, wl, "Nikon 5100", output="srgb", white="D65")
    raw = render.emulate_camera(ref, wl, "Nikon 5100", output="srgb", white="D65", ccm=None)
    assert _psnr(fitted, cie) > 35.0
    assert _psnr(fitted, cie) > _psnr(raw, cie) + 5.0
    M = render.fit_ccm("Nikon 5100", wl)
    np.testing.assert_allclose(M.sum(axis=0), 1.0, atol=1e-9)  # white preserved
    # camera_matrix is the linear part of the emulation
    lin = render.emulate_camera(ref, wl, "Nikon 5100", output="camera")
    Mc = render.camera_matrix("Nikon 5100", wl)
    np.testing.assert_allclose(lin, np.moveaxis(ref, 0, -1) @ Mc, rtol=1e-4, atol=1e-5)


def test_exposure_options_and_mask():
    wl = np.arange(410.0, 701.0, 10.0)
    rng = np.random.default_rng(0)
    cube = rng.uniform(0, 0.4, (wl.size, 8, 9)).astype(np.float32)
    e = render.emulate_camera(cube, wl, exposure="percentile", exposure_percentile=100)
    assert np.isclose(e.max(), 1.0, atol=1e-6)
    np.testing.assert_allclose(render.emulate_camera(cube, wl, exposure=2.0),
                               2 * render.emulate_camera(cube, wl), rtol=1e-6)
    m = np.ones((8, 9), bool)
    m[2, 3] = False
    out = render.emulate_camera(cube, wl, mask=m, fill=-1.0)
    assert np.all(out[2, 3] == -1.0) and np.all(out[m] >= 0)
    with pytest.raises(InvalidInputError):
        render.emulate_camera(cube, wl, exposure="bright")
    with pytest.raises(InvalidInputError):
        render.emulate_camera(cube, wl[:-1])
    with pytest.raises(InvalidInputError):
        render.emulate_camera(cube, wl, output="xyz")


def test_streaming_emulation_equals_in_memory(planes, tmp_path):
    cube, wl = planes.gt_cube, planes.cube_wavelengths
    path = write_cube_h5(tmp_path / "cube.h5", cube, wl, compression=None)
    kw = dict(camera="Nikon 5100", output="srgb", exposure="percentile")
    mem = render.emulate_camera(cube, wl, **kw)
    assert mem.shape == cube.shape[:2] + cube.shape[3:] + (3,)
    with open_cube_h5(path) as cf:
        disk = render.emulate_camera(cf, **kw)
        np.testing.assert_array_equal(disk, mem)
        disk_ds = render.emulate_camera(cf.cube, cf.wavelengths, **kw)  # raw h5py dataset
        np.testing.assert_array_equal(disk_ds, mem)
        one = render.emulate_camera(cf, camera="Nikon 5100", views="reference")
        np.testing.assert_allclose(one, render.emulate_camera(cube[2, 2], wl, "Nikon 5100"),
                                   atol=1e-6)
        some = render.emulate_camera(cf, camera="CIE 1931", views=[(0, 0), (4, 5)])
        assert some.shape == (2,) + cube.shape[3:] + (3,)
        # refocusing streams too (a camera, and weights that need only some bands)
        r_disk = render.refocus(cf, planes.offsets, 1.5, "Nikon 5100")
        w = np.zeros(wl.size)
        w[[3, 7, 20]] = (1.0, 2.0, 0.5)
        w_disk = render.refocus(cf, planes.offsets, -0.5, w)
    np.testing.assert_array_equal(
        r_disk, render.refocus(cube, planes.offsets, 1.5, "Nikon 5100", wavelengths=wl))
    np.testing.assert_allclose(
        w_disk, render.refocus(cube, planes.offsets, -0.5, w, wavelengths=wl), atol=1e-6)
    # a file's mask is honoured: masked pixels get `fill` / are left out of the average
    mask = np.ones(cube.shape[:2] + cube.shape[3:], bool)
    mask[:, :, 5, 7] = False
    mask[0, 0] = False
    bad = cube.copy()
    bad[0, 0] = 9.0
    path = write_cube_h5(tmp_path / "masked.h5", bad, wl, mask=mask, compression="lzf")
    with open_cube_h5(path) as cf:
        e = render.emulate_camera(cf, fill=-1.0)
        assert np.all(e[:, :, 5, 7] == -1.0) and np.all(e[1, 1, 5, 8] >= 0)
        r = render.refocus(cf, planes.offsets, 0.0, None)
        r_unmasked = render.refocus(cf, planes.offsets, 0.0, None, mask=False)
    ref_mean = np.delete(cube.reshape((-1,) + cube.shape[2:]), 0, axis=0).mean(axis=0)
    np.testing.assert_allclose(np.delete(r, 7, axis=2)[:, 5], np.delete(ref_mean, 7, axis=2)[:, 5],
                               atol=1e-5)
    assert np.all(r[:, 5, 7] == 0.0)  # no valid sample: fill
    assert r_unmasked.max() > 0.2 and np.abs(r_unmasked - r)[:, 10:, :].max() > 0.1


# ------------------------------------------------------------------------------ refocusing

def test_refocus_is_sharp_at_the_true_disparity(planes):
    cube, wl, off = planes.gt_cube, planes.cube_wavelengths, planes.offsets
    H, W = cube.shape[-2:]
    objs = SCENES["planes"]["objects"]
    boxes = {}
    for o in objs[1:]:
        x0, y0, x1, y1 = o["rect"]
        boxes[o["disparity"]] = (int(y0 * H) + 3, int(y1 * H) - 3, int(x0 * W) + 3,
                                 int(x1 * W) - 3)
    ds = [-1.5, -0.75, 0.0, 0.75, 1.5]
    # the cube, and the raw H-LF views (one band per view: misfocused views of different bands
    # add spurious detail, so the margin is smaller there, especially with Munsell chips)
    for src, kw, ratio in ((cube, dict(wavelengths=wl), 3.0), (planes, {}, 1.2)):
        stack = render.focal_stack(src, None if src is planes else off, ds, "CIE 1931", **kw)
        for d_true, box in boxes.items():
            sharp = [_lap_var(img, box) for img in stack]
            best = sharp[ds.index(d_true)]
            others = max(s for d, s in zip(ds, sharp) if d != d_true)
            assert best > ratio * others, (d_true, sharp)


def test_single_band_refocus_equals_reference_band_on_a_plane(one_plane):
    lf = one_plane
    cube, wl = lf.gt_cube, lf.cube_wavelengths
    ref = cube[lf.reference]
    for lam in (410.0, 550.0, 700.0):
        b = int(np.argmin(np.abs(wl - lam)))
        img, cnt = render.refocus(cube, lf.offsets, 1.0, lam, wavelengths=wl, return_counts=True)
        assert img.shape == ref.shape[1:]
        np.testing.assert_allclose(img, ref[b], atol=1e-5)
        assert cnt.max() == 30 and cnt.min() >= 1  # border pixels average fewer views
    # all bands at once, and from the raw H-LF views (one view sees 550 nm)
    np.testing.assert_allclose(render.refocus(cube, lf.offsets, 1.0, None, wavelengths=wl), ref,
                               atol=1e-5)
    np.testing.assert_allclose(render.refocus(lf, None, 1.0, 550.0), ref[14], atol=1e-5)
    # a weight vector is the weighted mean of the bands
    w = np.linspace(0, 1, wl.size)
    np.testing.assert_allclose(render.refocus(cube, lf.offsets, 1.0, w, wavelengths=wl),
                               np.tensordot(w / w.sum(), ref, axes=1), atol=1e-5)
    with pytest.raises(InvalidInputError):
        render.refocus(cube, lf.offsets, 1.0, 800.0, wavelengths=wl)


def test_refocus_excludes_outside_samples_instead_of_zero_filling():
    R, C, B, H, W = 3, 4, 5, 10, 12
    wl = np.linspace(450, 650, B)
    cube = np.full((R, C, B, H, W), 0.7, np.float32)
    img, cnt = render.refocus(cube, None, 2.5, None, wavelengths=wl, return_counts=True)
    np.testing.assert_allclose(img, 0.7, atol=1e-6)  # no darkening at the borders
    assert cnt.min() < R * C and cnt.max() == R * C
    # a masked view is left out
    mask = np.ones((R, C, H, W), bool)
    cube2 = cube.copy()
    cube2[0, 0] = 5.0
    mask[0, 0] = False
    np.testing.assert_allclose(render.refocus(cube2, None, 0.0, None, wavelengths=wl, mask=mask),
                               0.7, atol=1e-6)
    # aperture 0: the reference only
    ap, cnt = render.refocus(cube2, None, 1.0, None, wavelengths=wl, aperture=0.0,
                             return_counts=True)
    assert cnt.max() == 1


def test_refocus_a_cube_without_wavelengths_by_weights(planes):
    """A cube whose wavelengths are unknown (all NaN) refocuses by band weights and all bands
    exactly as with wavelengths; a camera or a single band, which need them, are refused."""
    cube, wl = planes.gt_cube, planes.cube_wavelengths
    unknown = np.full(wl.size, np.nan)
    w = np.linspace(0.0, 1.0, wl.size)
    for profile in (w, None):
        for d in (0.0, 1.5):
            np.testing.assert_array_equal(
                render.refocus(cube, planes.offsets, d, profile, wavelengths=unknown),
                render.refocus(cube, planes.offsets, d, profile, wavelengths=wl))
    for profile in ("CIE 1931", float(wl[3])):
        with pytest.raises(InvalidInputError, match="unknown"):
            render.refocus(cube, planes.offsets, 0.0, profile, wavelengths=unknown)


def test_refocus_camera_is_linear_and_views_are_white_balanced(planes):
    cube, wl, off = planes.gt_cube, planes.cube_wavelengths, planes.offsets
    bands = render.refocus(cube, off, 0.75, None, wavelengths=wl)
    for out in ("camera", "srgb"):
        a = render.refocus(cube, off, 0.75, "Nikon 5100", wavelengths=wl, output=out)
        b = render.emulate_camera(bands, wl, "Nikon 5100", output=out)
        np.testing.assert_allclose(a, b, atol=2e-5)
    # raw views with a flat scene: a camera profile gives grey
    flat = planes.replace(views=np.full_like(planes.views, 0.6))
    rgb = render.refocus(flat, None, 0.3, "Nikon 5100")
    np.testing.assert_allclose(rgb, 0.6, atol=1e-5)
    rgb = render.refocus(flat, None, 0.3, "CIE 1931", output="srgb")
    np.testing.assert_allclose(rgb, rgb[..., :1].repeat(3, -1), atol=1e-5)


def test_all_focus_reproduces_the_reference_cube(integer_scene, planes):
    lf = integer_scene
    cube, wl = lf.gt_cube, lf.cube_wavelengths
    ref, gt = cube[lf.reference], lf.gt_disparity[lf.reference]
    edges = ndimage.binary_dilation(np.abs(ndimage.laplace(gt)) > 1e-6, iterations=8)
    plain = render.all_focus(cube, lf.offsets, gt, None, wavelengths=wl, occlusion="none")
    assert _psnr(plain[:, ~edges], ref[:, ~edges]) > 50.0  # away from occlusions
    for occ, vd in (("views", lf.gt_disparity), ("zbuffer", None)):
        af = render.all_focus(cube, lf.offsets, gt, None, wavelengths=wl, occlusion=occ,
                              view_disparities=vd)
        assert _psnr(af, ref) > 60.0, occ  # occlusion check: everywhere
    assert _psnr(plain, ref) < 60.0
    # half-pixel shifts (SCENES['planes']): bilinear blur, still far better than any single focus
    ref2, gt2 = planes.gt_cube[planes.reference], planes.gt_disparity[planes.reference]
    kw = dict(wavelengths=planes.cube_wavelengths)
    af2 = render.all_focus(planes.gt_cube, planes.offsets, gt2, None, **kw)
    best_single = max(_psnr(render.refocus(planes.gt_cube, planes.offsets, d, None, **kw), ref2)
                      for d in (-1.5, 0.0, 1.5))
    assert _psnr(af2, ref2) > best_single + 5.0
    # camera profile: equals the emulation of the all-focus cube
    rgb = render.all_focus(cube, lf.offsets, gt, "CIE 1931", wavelengths=wl, output="srgb")
    np.testing.assert_allclose(rgb, render.emulate_camera(ref, wl, output="srgb"), atol=1e-4)
    with pytest.raises(InvalidInputError):
        render.all_focus(cube, lf.offsets, gt, None, wavelengths=wl, occlusion="views")


# ------------------------------------------------------------------------------ sweep, spectra

def test_focal_sweep_writes_frames_gif_and_mp4(planes, tmp_path):
    from PIL import Image

    ds = np.linspace(-1.5, 1.5, 4)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = render.focal_sweep(planes.gt_cube, planes.offsets, ds, "CIE 1931",
                                 out_dir=tmp_path / "sweep", fps=4,
                                 wavelengths=planes.cube_wavelengths)
    assert len(res["frames"]) == 4 and all(p.is_file() for p in res["frames"])
    with Image.open(res["gif"]) as im:
        assert im.n_frames == 4
        assert im.size == (planes.gt_cube.shape[-1], planes.gt_cube.shape[-2])
    if res["mp4"] is None:  # this OpenCV cannot write MPEG-4: a warning says so
        assert any("MP4" in str(w.message) for w in caught)
    else:
        import cv2

        cap = cv2.VideoCapture(str(res["mp4"]))
        n = 0
        while cap.read()[0]:
            n += 1
        cap.release()
        assert n == 4
    assert not list((tmp_path / "sweep").glob(".*partial*"))  # atomic writes left nothing
    # a single band of the raw views, GIF only
    res = render.focal_sweep(planes, None, [0.0, 1.5], 550.0, out_dir=tmp_path / "band",
                             formats=("gif",), annotate=False)
    assert res["mp4"] is None and len(res["frames"]) == 2


@pytest.mark.parametrize("profile", [None, "bands", "BANDS"])
def test_focal_sweep_of_every_band_is_refused_before_any_work(planes, tmp_path, profile):
    """A sweep's frames are pictures: every band (one image per band) is refused before the
    stack is refocused, and no folder is made."""
    from conftest import LongWork, long_work_stopped

    with long_work_stopped(), pytest.raises(InvalidInputError, match="not all bands"):
        try:
            render.focal_sweep(planes.gt_cube, planes.offsets, [0.0, 1.0], profile,
                               wavelengths=planes.cube_wavelengths, out_dir=tmp_path / "s")
        except LongWork:
            pytest.fail("refocused before the refusal")
    assert not (tmp_path / "s").exists()


def _read_video(path):
    """Every frame of a video (RGB uint8) and its fourcc, as OpenCV reads them back."""
    import cv2

    cap = cv2.VideoCapture(str(path))
    try:
        frames = []
        while True:
            ok, f = cap.read()
            if not ok:
                break
            frames.append(f[..., ::-1])
        fourcc = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode("ascii")
    finally:
        cap.release()
    return frames, fourcc


def test_focal_sweep_webm_is_vp9_for_browsers(planes, tmp_path, capfd):
    """The MP4 ('mp4v', MPEG-4 part 2) does not play in browsers; the WebM (VP9) does. It reads
    back with every frame, the frame size and the frames' brightness (a lossy codec: means
    within a few levels); OpenCV's 'tag not supported' notice stays off stderr."""
    from PIL import Image

    ds = np.linspace(-1.5, 1.5, 5)
    res = render.focal_sweep(planes.gt_cube, planes.offsets, ds, "CIE 1931",
                             out_dir=tmp_path / "sweep", fps=4, formats=("webm",),
                             wavelengths=planes.cube_wavelengths, annotate=False)
    assert res["gif"] is None and res["mp4"] is None
    assert res["webm"] == tmp_path / "sweep" / "refocus.webm"
    frames, fourcc = _read_video(res["webm"])
    assert fourcc == "VP90" and len(frames) == 5
    H, W = planes.gt_cube.shape[-2:]
    assert all(f.shape == (H, W, 3) for f in frames)
    for got, png in zip(frames, res["frames"]):
        with Image.open(png) as im:
            want = np.asarray(im.convert("RGB"), dtype=np.float64)
        assert abs(got.mean() - want.mean()) < 6.0
        assert np.abs(got.astype(np.float64).mean(axis=(0, 1)) - want.mean(axis=(0, 1))).max() < 10
    assert not list((tmp_path / "sweep").glob(".*partial*"))
    assert "OpenCV" not in capfd.readouterr().err
    with pytest.raises(InvalidInputError, match="'gif', 'mp4' and 'webm'"):
        render.focal_sweep(planes.gt_cube, planes.offsets, ds, "CIE 1931",
                           out_dir=tmp_path / "x", formats=("avi",))


def test_focal_sweep_videos_of_an_odd_size(planes, tmp_path):
    """MPEG-4 and VP9 code even sizes only (VP9 dropped the odd row and column): both videos
    pad the frames to the next even size, every frame there."""
    cube = planes.gt_cube[..., :47, :59]
    res = render.focal_sweep(cube, planes.offsets, [-1.0, 0.0, 1.0], "CIE 1931",
                             out_dir=tmp_path / "odd", fps=4, formats=("mp4", "webm"),
                             wavelengths=planes.cube_wavelengths)
    for key in ("mp4", "webm"):
        if res[key] is None and key == "mp4":  # this OpenCV cannot write MPEG-4
            continue
        frames, _ = _read_video(res[key])
        assert len(frames) == 3 and all(f.shape == (48, 60, 3) for f in frames), key


def test_focal_sweep_without_a_video_codec_warns_and_writes_the_gif(planes, tmp_path,
                                                                     monkeypatch):
    """An OpenCV build that cannot open the VP9 writer: a RuntimeWarning names the WebM, its
    entry is None, the GIF is still written and no temporary file is left."""
    import cv2

    class Closed:
        def __init__(self, *args, **kwargs):
            pass

        def isOpened(self):
            return False

        def release(self):
            pass

    monkeypatch.setattr(cv2, "VideoWriter", Closed)
    with pytest.warns(RuntimeWarning, match="no WebM written.*VP90.*VP9 encoder"):
        res = render.focal_sweep(planes.gt_cube, planes.offsets, [0.0, 1.0], "CIE 1931",
                                 out_dir=tmp_path / "s", formats=("gif", "webm"),
                                 wavelengths=planes.cube_wavelengths)
    assert res["webm"] is None and res["gif"].is_file()
    assert sorted(q.name for q in (tmp_path / "s").iterdir()) == [
        "refocus.gif", "refocus_000.png", "refocus_001.png", "refocus_frames.csv"]


def test_spectrum_at_and_figure(planes, tmp_path):
    cube, wl = planes.gt_cube, planes.cube_wavelengths
    s = render.spectrum_at(cube, wl, 10, 12)
    np.testing.assert_allclose(s, cube[2, 2, :, 12, 10], rtol=1e-6)
    s = render.spectrum_at(cube, wl, 10, 12, view=(1, 4))
    np.testing.assert_allclose(s, cube[1, 4, :, 12, 10], rtol=1e-6)
    mid = render.spectrum_at(cube[0, 0], wl, 10.5, 12.0)
    np.testing.assert_allclose(mid, cube[0, 0, :, 12, 10:12].mean(-1), rtol=1e-5)
    both = render.spectrum_at(cube, wl, [1.0, 1000.0], [2.0, 3.0])
    assert both.shape == (2, wl.size) and np.all(np.isnan(both[1]))
    p = render.save_spectrum_figure(tmp_path / "spectra.png", cube, wl,
                                    points=[(10, 12), (30, 20), (50, 30)])
    assert p.is_file() and p.stat().st_size > 1000


def test_fast_samplers_match_warp_sample_bilinear(rng):
    from hyperlf.warp import sample_bilinear

    img = rng.random((9, 11, 2)).astype(np.float32)
    yy, xx = np.mgrid[0:9, 0:11].astype(np.float64)
    for sx, sy in ((0.0, 0.0), (1.0, -2.0), (0.3, -1.7), (-2.5, 0.25), (10.0, 0.0), (-0.0, 8.0)):
        want, wv = sample_bilinear(img, xx + sx, yy + sy, fill=0.0)
        got, gv = render._sample_shift(img, sx, sy)
        np.testing.assert_array_equal(gv, wv)
        np.testing.assert_allclose(got, want, atol=1e-6)
    qx = xx + rng.uniform(-3, 3, xx.shape)
    qy = yy + rng.uniform(-3, 3, yy.shape)
    want, wv = sample_bilinear(img, qx, qy, fill=0.0)
    got, gv = render._sample_map(img, qx, qy)
    np.testing.assert_array_equal(gv, wv)
    np.testing.assert_allclose(got, want, atol=1e-6)


def test_raw_view_camera_refocus_equals_emulated_reference_on_a_plane(one_plane):
    """Refocusing the raw H-LF (one band per view) with a camera profile at the plane's
    disparity gives the camera image of the reference cube wherever all 30 views see it."""
    lf = one_plane
    for out in ("camera", "srgb"):
        got, cnt = render.refocus(lf, None, 1.0, "Nikon 5100", output=out, return_counts=True)
        want = render.emulate_camera(lf.gt_cube[lf.reference], lf.cube_wavelengths, "Nikon 5100",
                                     output=out)
        full = cnt == lf.n_views
        assert full.sum() > 0.5 * full.size
        np.testing.assert_allclose(got[full], want[full], atol=1e-5)


def test_a_band_profile_picks_a_band_only_within_a_filter_width():
    """band:NM takes the nearest band within 5 nm (and half the spacing), not any band: two
    bands 290 nm apart do not make 550 nm mean 410 nm."""
    from hyperlf.render import BAND_TOLERANCE_NM, band_index

    assert band_index([410.0, 548.7, 700.0], 550) == 1
    assert band_index(np.linspace(410, 700, 30), 523) == 11  # 10 nm spacing: 520 is within 3 nm
    with pytest.raises(InvalidInputError, match="no band at 550 nm.*nearest 410"):
        band_index([410.0, 700.0], 550)
    with pytest.raises(InvalidInputError, match="within 2.5 nm"):
        band_index([500.0, 505.0], 510)
    assert BAND_TOLERANCE_NM == 5.0
