"""Tests of hyperlf.spectral (colour matching, cameras, dominant wavelength, data loaders)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hyperlf import spectral as sp
from hyperlf.datasets import ENV_VAR, has_data
from hyperlf.errors import DataNotFoundError, FormatError, InvalidInputError

CIE = "CIE 1931 2 Degree Standard Observer"
E = (1 / 3, 1 / 3)
D65 = (0.3127, 0.3290)


def _need(name: str) -> None:
    if not has_data(name):
        pytest.skip(f"needs the real data: set {ENV_VAR} to the shared data folder ({name})")


@pytest.fixture(scope="module")
def colour():
    return pytest.importorskip("colour")


@pytest.fixture(scope="module")
def locus_points(colour):
    """A few thousand random chromaticities strictly inside the CIE 1931 spectral locus."""
    from matplotlib.path import Path as MPath

    c = colour.MSDS_CMFS[CIE]
    xy_s = c.values[:, :2] / c.values.sum(1, keepdims=True)
    rng = np.random.default_rng(7)
    pts = rng.uniform([0, 0], [0.75, 0.85], (12000, 2))
    pts = pts[MPath(xy_s).contains_points(pts)]
    return pts[:4000]


# --- import cost -----------------------------------------------------------------------------

def test_import_does_not_load_colour():
    code = "import sys, hyperlf.spectral; print('colour' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# --- CMFs, XYZ, RGB --------------------------------------------------------------------------

def test_cmfs_match_colour(colour):
    table = colour.MSDS_CMFS[CIE]
    wl = np.array([380.0, 445.0, 555.0, 600.0, 700.0])
    np.testing.assert_allclose(sp.cmfs(wl), table[wl], rtol=0, atol=1e-12)
    # between 1 nm samples: linear interpolation, close to colour's (Sprague) interpolation
    wl_half = np.array([450.5, 555.5, 640.25])
    np.testing.assert_allclose(sp.cmfs(wl_half), table[wl_half], atol=2e-4)
    # zero outside the table
    assert np.all(sp.cmfs([300.0, 900.0]) == 0)


def test_flat_spectrum_is_white():
    for wl in (np.arange(380, 781, 5.0), np.array([410, 430, 470, 520, 600, 690.0]),
               np.arange(410, 701, 10.0)[::-1]):
        xyz = sp.spectrum_to_xyz(np.ones(wl.size), wl)
        assert xyz[1] == pytest.approx(1.0, abs=1e-12)
        rgb = sp.spectrum_to_rgb(np.ones(wl.size), wl)
        np.testing.assert_allclose(rgb, 1.0, atol=1e-12)
        rgb_cam = sp.spectrum_to_rgb(np.ones(wl.size), wl, camera="Sigma SDMerill (NPL)")
        np.testing.assert_allclose(rgb_cam, 1.0, atol=1e-12)
    # perfect reflector under D65 has Y = 1 and maps to sRGB white
    wl = np.arange(380, 781, 5.0)
    xyz = sp.spectrum_to_xyz(np.ones(wl.size), wl, illuminant="D65")
    np.testing.assert_allclose(sp.xyz_to_srgb_linear(xyz), 1.0, atol=2e-3)
    # equal-energy white adapts to sRGB white with the white= option
    xyz_e = sp.spectrum_to_xyz(np.ones(wl.size), wl)
    np.testing.assert_allclose(sp.xyz_to_srgb_linear(xyz_e, white=E), 1.0, atol=1e-3)


@pytest.mark.parametrize("white", [(0.0, 0.0), (0.3, 0.0), (0.3, -0.1), (0.5, -2.0)])
def test_white_that_no_adaptation_starts_from_is_refused(white):
    # y = 0 divided by zero (a warning, then NaN colours): a one-line error now
    with np.errstate(all="raise"):
        with pytest.raises(InvalidInputError, match="white must be the xy chromaticity"):
            sp.xyz_to_srgb_linear(np.ones(3), white=white)


def test_white_of_two_far_bands_still_adapts_and_d65_is_no_adaptation():
    # the white of two bands far apart (render's rough guess) still adapts, to finite values
    with np.errstate(all="raise"):
        assert np.isfinite(sp.xyz_to_srgb_linear(np.ones(3), white=(0.205, 0.0199))).all()
    d65 = sp.xyz_to_srgb_linear(np.array([0.2, 0.3, 0.4]), white=(0.3127, 0.3290))
    np.testing.assert_allclose(d65, sp.xyz_to_srgb_linear(np.array([0.2, 0.3, 0.4])),
                               atol=1e-12)


def test_spectrum_to_xyz_matches_colour(colour):
    wl = np.arange(380, 781, 5.0)
    refl = sp.reflectance_library("colorchecker", wl)[1][:6]
    ours = sp.spectrum_to_xyz(refl, wl, illuminant="D65")
    shape = colour.SpectralShape(380, 780, 5)
    ill = colour.SDS_ILLUMINANTS["D65"].copy().align(shape)
    ref = np.array([
        colour.sd_to_XYZ(colour.SpectralDistribution(r, wl), illuminant=ill,
                         cmfs=colour.MSDS_CMFS[CIE].copy().align(shape), method="Integration")
        for r in refl
    ]) / 100
    np.testing.assert_allclose(ours, ref, atol=2e-3)


def test_spectrum_axis_and_dtype():
    wl = np.arange(410, 701, 10.0)
    cube = np.random.default_rng(0).random((2, 3, wl.size, 4, 5)).astype(np.float32)
    rgb = sp.spectrum_to_rgb(cube, wl, axis=2)
    assert rgb.shape == (2, 3, 3, 4, 5) and rgb.dtype == np.float32
    ref = sp.spectrum_to_rgb(np.moveaxis(cube, 2, -1), wl)
    np.testing.assert_allclose(np.moveaxis(rgb, 2, -1), ref, rtol=1e-5)
    with pytest.raises(InvalidInputError, match="wavelengths"):
        sp.spectrum_to_rgb(cube, wl[:-1], axis=2)


def test_srgb_transfer_round_trip():
    x = np.linspace(-0.2, 1.2, 2001)
    np.testing.assert_allclose(sp.srgb_to_linear(sp.linear_to_srgb(x)), x, atol=1e-12)
    np.testing.assert_allclose(sp.linear_to_srgb(sp.srgb_to_linear(x)), x, atol=1e-12)
    assert sp.srgb_to_linear(np.float32(1.0)) == pytest.approx(1.0)
    with pytest.raises(InvalidInputError, match="divide by 255"):  # 8-bit values refused
        sp.srgb_to_linear(np.array([0, 128, 255], np.uint8))
    assert sp.srgb_to_linear(0.04045) == pytest.approx(0.04045 / 12.92)
    assert sp.linear_to_srgb(np.array([0.5], np.float32)).dtype == np.float32


def test_xyz_srgb_matrix(colour):
    xyz = np.random.default_rng(1).random((100, 3))
    ref = colour.XYZ_to_sRGB(xyz, apply_cctf_encoding=False)
    np.testing.assert_allclose(sp.xyz_to_srgb_linear(xyz), ref, atol=5e-4)
    np.testing.assert_allclose(sp.srgb_linear_to_xyz(sp.xyz_to_srgb_linear(xyz)), xyz, atol=1e-12)
    np.testing.assert_allclose(sp.xyz_to_srgb(xyz, clip=True),
                               sp.linear_to_srgb(np.clip(sp.xyz_to_srgb_linear(xyz), 0, 1)))


def test_xyz_to_xy_safe_for_zero():
    xy = sp.xyz_to_xy(np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.2, 0.6, 0.2]]))
    np.testing.assert_allclose(xy, [[1 / 3, 1 / 3], [1 / 3, 1 / 3], [0.2, 0.6]])


def test_illuminant_spd():
    wl = np.arange(400, 701, 10.0)
    for name in ("D65", "e", "A"):
        spd = sp.illuminant_spd(name, wl)
        assert spd.shape == wl.shape and spd.mean() == pytest.approx(1.0)
    np.testing.assert_allclose(sp.illuminant_spd("E", wl), 1.0)
    a = sp.illuminant_spd("A", wl)
    assert a[-1] > a[0]  # incandescent: rising towards red
    with pytest.raises(InvalidInputError, match="illuminant"):
        sp.illuminant_spd("D66x", wl)


# --- RGB -> spectrum ---------------------------------------------------------------------------

@pytest.mark.parametrize("wl, tol", [
    # the basis is tabulated at 5 nm: only the CMF subsampling and matrix rounding remain
    (np.arange(380, 781, 5.0), 1e-3),
    # 1 nm: linear interpolation of the 5 nm basis between its nodes
    (np.arange(380, 781, 1.0), 3e-3),
    # the paper's 30 bands 410-700 nm: a coarse 10 nm Riemann sum missing 380-410, 700-780 nm
    (np.arange(410, 701, 10.0), 2e-2),
])
def test_rgb_to_spectrum_round_trip(wl, tol):
    rgb = np.random.default_rng(2).random((3000, 3))
    spectra = sp.rgb_to_spectrum(rgb, wl)
    assert spectra.shape == (3000, wl.size)
    assert spectra.min() >= 0 and spectra.max() <= 1  # physical reflectances
    back = sp.xyz_to_srgb_linear(sp.spectrum_to_xyz(spectra, wl, illuminant="D65"))
    assert np.abs(back - rgb).max() < tol
    np.testing.assert_allclose(sp.rgb_to_spectrum(np.ones(3), wl), 1.0, atol=1e-4)  # basis sums to 1 +- 1e-5


# --- dominant wavelength -------------------------------------------------------------------

@pytest.mark.parametrize("white", [E, D65])
def test_dominant_wavelength_matches_colour(colour, locus_points, white):
    ours, purple = sp.dominant_wavelength(locus_points, white)
    ref, xy_wl, xy_cwl = colour.dominant_wavelength(locus_points, np.array(white))
    assert np.array_equal(purple, ref < 0)
    assert (~purple).sum() > 2000 and purple.sum() > 200
    # colour returns the nearest 1 nm table sample, ours is continuous: within half a step
    # (+ float rounding) wherever the locus is well conditioned. Beyond ~690 nm (and below
    # 400 nm) the CIE 1931 locus is nearly one point and the wavelength is ill-defined
    # (colour may answer any of 700-830 nm); there, the locus points must agree instead.
    good = (np.abs(ref) >= 400) & (np.abs(ref) <= 690)
    assert good.mean() > 0.95
    err = np.abs(ours - ref)
    assert err[good & ~purple].max() <= 0.5 + 1e-6
    # purples: negative complementary wavelength, as colour does
    assert np.all(ours[purple] < 0)
    assert err[good & purple].max() <= 0.5 + 1e-6
    locus_xy = sp.xyz_to_xy(sp.cmfs(np.abs(ours)))
    ref_xy = np.where(purple[:, None], xy_cwl, xy_wl)
    assert np.abs(locus_xy - ref_xy).max() < 5e-4


def test_dominant_wavelength_special_points():
    wl, purple = sp.dominant_wavelength(np.array([[1 / 3, 1 / 3], [np.nan, 0.3]]))
    assert np.all(np.isnan(wl)) and not purple.any()
    # a spectral colour maps to its own wavelength
    lam = np.array([450.0, 500.0, 550.0, 600.0, 650.0])
    xy = sp.xyz_to_xy(sp.cmfs(lam))
    np.testing.assert_allclose(sp.dominant_wavelength(xy)[0], lam, atol=0.05)
    with pytest.raises(InvalidInputError, match="white"):
        sp.dominant_wavelength(xy, white=(0.9, 0.9))


def test_dominant_wavelength_for_filters():
    lo, hi = 410.0, 700.0
    # achromatic -> middle
    near_white = np.array([[1 / 3 + 0.005, 1 / 3], [1 / 3, 1 / 3 - 0.009], [0.0, 0.0]]) \
        + np.array([[0, 0], [0, 0], [1 / 3, 1 / 3]])
    np.testing.assert_allclose(
        sp.dominant_wavelength_for_filters(near_white, lo, hi, achromatic_radius=0.01), 555.0)
    # spectral colours inside the range keep their wavelength, outside are clipped
    lam = np.array([405.0, 430.0, 550.0, 690.0])
    xy = sp.xyz_to_xy(sp.cmfs(lam))
    out = sp.dominant_wavelength_for_filters(xy, 450.0, 650.0)
    np.testing.assert_allclose(out, [450.0, 450.0, 550.0, 650.0], atol=0.05)
    # purples: reddish -> upper end, bluish -> lower end
    red_purple = np.array([0.45, 0.22])   # close to the red end of the purple line
    blue_purple = np.array([0.25, 0.10])  # close to the violet end
    wl, purple = sp.dominant_wavelength(np.stack([red_purple, blue_purple]))
    assert purple.all()
    out = sp.dominant_wavelength_for_filters(np.stack([red_purple, blue_purple]), lo, hi)
    np.testing.assert_array_equal(out, [hi, lo])


def test_dominant_wavelength_for_filters_always_in_range(locus_points):
    out = sp.dominant_wavelength_for_filters(locus_points, 430.0, 650.0, white=D65)
    assert out.shape == (len(locus_points),)
    assert np.all((out >= 430.0) & (out <= 650.0))


# --- cameras ---------------------------------------------------------------------------------

def test_camera_sensitivities_colour_camera(colour):
    wl = np.arange(380, 781, 5.0)
    s = sp.camera_sensitivities("Nikon 5100 (NPL)", wl)
    np.testing.assert_allclose(s, colour.MSDS_CAMERA_SENSITIVITIES["Nikon 5100 (NPL)"].values)
    s2 = sp.camera_sensitivities("sigma sdmerill", wl)  # case-insensitive substring
    assert s2.shape == (wl.size, 3)
    assert np.all(s2[wl < 400] == 0) and np.all(s2[wl > 680] == 0)  # zero outside 400-680 nm
    np.testing.assert_allclose(sp.camera_sensitivities("XYZ", wl), sp.cmfs(wl))
    names = sp.list_cameras()
    assert {"CIE 1931", "XYZ", "Nikon 5100 (NPL)"} <= set(names)


def test_unknown_camera_lists_close_names():
    # a unique substring is accepted ("Sigma SDMeril"), so use a typo:
    with pytest.raises(InvalidInputError) as info:
        sp.camera_sensitivities("Sigmma SDMeril", np.arange(400, 701, 10.0))
    msg = str(info.value)
    assert "Sigma SDMerill (NPL)" in msg and "\n" not in msg


def test_camera_csv(tmp_path):
    wl = np.arange(400, 701, 10.0)
    table = np.column_stack([wl, np.exp(-((wl - 600) / 40) ** 2),
                             np.exp(-((wl - 540) / 40) ** 2), np.exp(-((wl - 450) / 30) ** 2)])
    p = tmp_path / "cam.csv"
    p.write_text("wavelength_nm,r,g,b\n" + "\n".join(",".join(f"{v:.6g}" for v in r) for r in table))
    w, s = sp.load_sensitivities_csv(p)
    np.testing.assert_allclose(w, wl)
    np.testing.assert_allclose(s, table[:, 1:], rtol=1e-5)
    q = tmp_path / "cam.txt"  # whitespace separated, no header
    q.write_text("\n".join(" ".join(f"{v:.6g}" for v in r) for r in table) + "\n")
    np.testing.assert_allclose(sp.camera_sensitivities(q, [405.0, 800.0]),
                               [0.5 * (s[0] + s[1]), [0, 0, 0]], rtol=1e-6)
    np.testing.assert_allclose(sp.camera_sensitivities(str(p), wl), s)
    rgb = sp.spectrum_to_rgb(np.ones(wl.size), wl, camera=p)
    np.testing.assert_allclose(rgb, 1.0)
    with pytest.raises(DataNotFoundError):
        sp.camera_sensitivities(tmp_path / "missing.csv", wl)


@pytest.mark.parametrize("content, match", [
    ("", "data row"),
    ("wavelength,r,g,b\n400,1,2\n410,1,2,3\n", "column"),
    ("400,1,2,3\n410,1,x,3\n", "non-numeric"),
    ("400,1,2,3\n400,1,2,3\n", "increasing"),
    ("400,1,2,3\n410,nan,2,3\n", "finite"),
])
def test_csv_malformed_examples(tmp_path, content, match):
    p = tmp_path / "bad.csv"
    p.write_text(content)
    with pytest.raises(FormatError, match=match):
        sp.load_sensitivities_csv(p)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(
    st.binary(max_size=300),
    st.lists(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                                st.text(alphabet="0123456789.-eE, \tabc", max_size=6)),
                      max_size=6).map(lambda r: ",".join(r)), max_size=8).map(
        lambda rows: "\n".join(rows).encode()),
))
def test_csv_parser_never_crashes(tmp_path, data):
    p = tmp_path / "fuzz.csv"
    p.write_bytes(data)
    try:
        w, s = sp.load_sensitivities_csv(p)
    except FormatError as exc:
        assert "\n" not in str(exc)
    else:
        assert w.ndim == 1 and s.shape == (w.size, 3) and np.all(np.diff(w) > 0)
        assert np.all(np.isfinite(s))


# --- filters ---------------------------------------------------------------------------------

def test_filter_response_shapes():
    wl = np.arange(400, 701, 10.0)
    d = sp.filter_response(550, wl)
    assert d.shape == wl.shape and d[15] == 1 and d.sum() == 1
    d2 = sp.filter_response([555.0, 400.0], wl)
    np.testing.assert_allclose(d2[0, 15:17], [0.5, 0.5])
    g = sp.filter_response(550, np.arange(400, 701, 1.0), "gaussian", fwhm=10)
    assert g.sum() == pytest.approx(1.0) and np.argmax(g) == 150
    # half maximum at +-5 nm
    assert g[155] / g[150] == pytest.approx(0.5, rel=1e-6)
    with pytest.raises(InvalidInputError, match="outside"):
        sp.filter_response(390, wl)
    with pytest.raises(InvalidInputError, match="shape"):
        sp.filter_response(550, wl, "boxcar")


@pytest.mark.parametrize("options, words", [
    # a text fwhm raised TypeError from np.isfinite; the option fuzzer's base call is a
    # Dirac filter, which ignores fwhm, so it never reached the Gaussian
    (dict(shape="gaussian", fwhm="x"), "fwhm must be a finite number in [0.001, 1000], got "
                                       "'x'"),
    (dict(shape="gaussian", fwhm=1e-300), "fwhm must be a finite number in [0.001, 1000]"),
    (dict(shape="gaussian", fwhm=1e308), "fwhm must be a finite number in [0.001, 1000]"),
    (dict(shape=["dirac"]), "shape must be one of dirac, gaussian, thorlabs, got ['dirac']"),
    (dict(shape="thorlabs", align=None), "align must be one of centroid, nominal, got None"),
    # a centre of 1e308 overflowed the Gaussian's square
    (dict(shape="gaussian", center_nm=1e308), "center_nm must be wavelengths in (0, 1e+06] nm"),
])
def test_filter_options_are_refused_by_name(options, words):
    with pytest.raises(InvalidInputError) as exc:
        sp.filter_response(**{"center_nm": 550, "wavelengths": np.arange(400, 701, 10.0),
                              **options})
    assert str(exc.value).startswith(words)


def test_a_scene_s_gaussian_filters_take_a_bounded_fwhm():
    """fwhm=1e308 overflowed the sampling grid's bounds (OverflowError from math.floor)."""
    from hyperlf import synthesis

    with pytest.raises(InvalidInputError,
                       match=r"^fwhm must be a finite number in \[0\.001, 1000\]"):
        synthesis.procedural_scene(seed=1, rows=2, cols=2, height=12, width=12,
                                   filter_shape="gaussian", fwhm=1e308)
    assert tuple(sp.FILTER_SHAPES) == ("dirac", "gaussian", "thorlabs")


def test_thorlabs_filters():
    _need("thorlabs")
    wl, trans, centres = sp.load_filter_transmissions()
    assert trans.shape == (centres.size, wl.size) and wl[0] == 380 and wl[-1] == 800
    assert 0 <= trans.min() and trans.max() <= 1 and trans.max() > 0.9
    fine = np.arange(380, 801, 1.0)
    r = sp.filter_response([430.0, 550.0], fine, "thorlabs")
    assert r.shape == (2, fine.size) and np.allclose(r.sum(1), 1)
    centroid = (r * fine).sum(1)
    np.testing.assert_allclose(centroid, [430.0, 550.0], atol=1.5)


# --- data files ------------------------------------------------------------------------------

def test_camspec():
    _need("camspec")
    cams = sp.load_camspec()
    assert len(cams) == 28
    for wl, s in cams.values():
        assert wl.shape == (33,) and s.shape == (33, 3)
        assert wl[0] == 400 and wl[-1] == 720
    assert "Canon 5DMarkII" in cams and "SONY NEX-5N" in cams
    assert "Nikon D5100" in sp.list_cameras()
    s = sp.camera_sensitivities("nikon d5100", cams["Nikon D5100"][0])
    np.testing.assert_allclose(s, cams["Nikon D5100"][1])
    with pytest.raises(InvalidInputError, match="ambiguous"):
        sp.camera_sensitivities("canon", [500.0])


def test_camspec_malformed(tmp_path):
    p = tmp_path / "cs.txt"
    p.write_text("header\n\nCam A\n" + "1 2 3\n" * 3)
    with pytest.raises(FormatError, match="33"):
        sp.load_camspec(p)
    p.write_text("header\nCam A\n" + " ".join(["1"] * 33) + "\n")
    with pytest.raises(FormatError, match="expected 3"):
        sp.load_camspec(p)
    p.write_text("Cam A\n" + (" ".join(["0.5"] * 33) + "\n") * 3)
    assert list(sp.load_camspec(p)) == ["Cam A"]
    with pytest.raises(DataNotFoundError):
        sp.load_camspec(tmp_path / "nope.txt")


def test_munsell():
    _need("munsell")
    wl, refl = sp.load_munsell()
    assert wl.shape == (421,) and wl[0] == 380 and wl[-1] == 800
    assert refl.shape == (1269, 421)
    assert 0 < refl.min() and refl.max() < 1
    w2, r2 = sp.reflectance_library("auto")
    assert r2.shape == (1269, 421)


def test_reflectance_library_colorchecker():
    wl, refl = sp.reflectance_library("colorchecker")
    assert refl.shape == (24, wl.size) and wl[0] == 380 and wl[-1] == 780
    wl2, refl2 = sp.reflectance_library("colorchecker", np.arange(410, 701, 10.0))
    assert refl2.shape == (24, 30)
    with pytest.raises(InvalidInputError):
        sp.reflectance_library("macbeth-ish")


def test_missing_data_errors(monkeypatch):
    monkeypatch.delenv(ENV_VAR, raising=False)
    with pytest.raises(DataNotFoundError, match=ENV_VAR):
        sp.load_munsell()
    with pytest.raises(DataNotFoundError, match=ENV_VAR):
        sp.load_camspec()
    wl, refl = sp.reflectance_library("auto")
    assert refl.shape[0] == 24


def test_wavelengths_unknown_only_for_all_nan():
    """All NaN is 'unknown'; a mix, numbers, empty input and non-numbers are not (the last
    are for as_wavelengths to refuse in one line)."""
    from hyperlf.spectral import as_wavelengths, wavelengths_unknown

    assert wavelengths_unknown([np.nan] * 3) and wavelengths_unknown(np.nan)
    for wl in ([500.0, np.nan], [500.0], [], ["a", "b"], None, {"x": 1}):
        assert not wavelengths_unknown(wl)
    with pytest.raises(InvalidInputError, match="numbers in nm"):
        as_wavelengths(["a", "b"])


def test_importing_colour_leaves_numpys_printing_alone():
    """colour-science sets numpy's legacy 1.13 printing on import; a library must not change
    how its user's arrays print."""
    code = ("import numpy as np; from hyperlf import spectral; "
            "spectral.cmfs(np.array([550.0])); "
            "print(np.get_printoptions()['legacy'], 'colour' in __import__('sys').modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "True"]
