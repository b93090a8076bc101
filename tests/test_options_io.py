"""Option values of the writers (:mod:`hyperlf.formats`) and of the stages of cube completion
(:mod:`hyperlf.completion`), fuzzed as in ``test_options``: every argument takes what it
documents or is refused with one line of a hyperlf error before any work, never a
``TypeError``, ``ValueError``, ``OverflowError``, ``ZeroDivisionError``, numba typing error
or numpy warning from deep inside. Every file goes into a temporary folder."""

from __future__ import annotations

import functools
import os
import tempfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf.errors import InvalidInputError
from test_options import JUNK, _build_or_refuse, _in_temp_folder, _keywords


def _inside(value) -> bool:
    """A fuzzed path that stays in the temporary folder (no absolute name, no '..')."""
    return not (isinstance(value, str) and (os.path.isabs(value) or ".." in value))


#: JUNK for any argument, paths among them: it is passed inside a temporary folder.
SAFE_JUNK = JUNK.filter(_inside)


def _fuzz(calls: dict, option: tuple[str, str], value) -> None:
    """Call ``calls[name]`` with ``keyword=value`` in a fresh temporary working folder; a
    numpy warning on the way is a failure too."""
    name, keyword = option
    with _in_temp_folder("error"):
        _build_or_refuse(calls[name][1], **{keyword: value})


@functools.lru_cache(maxsize=1)
def _scene():
    from hyperlf import synthesis

    return synthesis.procedural_scene(seed=1, rows=2, cols=2, height=12, width=16,
                                      disparity_range=(-1.0, 1.0))


def _cube_writer(wavelengths, **kw):
    """:class:`CubeWriter` filling a 1 x 2 grid view by view; ``kw`` for the constructor or
    for :meth:`CubeWriter.write_view` (of view (0, 0), the other one written plainly)."""
    from hyperlf.formats import CubeWriter

    view = {k: kw.pop(k) for k in ("r", "c", "cube_rc", "mask_rc") if k in kw}
    options = {"path": "w.h5", "shape": (1, 2, 3, 6, 8), "wavelengths": wavelengths, **kw}
    with CubeWriter(**options) as w:
        w.write_view(**{"r": 0, "c": 0, "cube_rc": np.ones((3, 6, 8)), **view})
        w.write_view(0, 1, np.ones((3, 6, 8)))


def _writer_calls():
    """Each writer with its required arguments, as ``name -> (function, call)``; the fuzzers
    set one keyword."""
    from hyperlf import formats
    from hyperlf.formats import hdf5, ply

    lf, rng = _scene(), np.random.default_rng(0)
    wl = np.array([450.0, 550.0, 650.0])
    pair = formats.StereoPair(left=rng.random((6, 8, 3)), right=rng.random((6, 8, 3)),
                              gt_disparity=np.full((6, 8), 2.0), scale=4.0, max_disparity=4)
    calls = {
        "write_pfm": (formats.write_pfm, {"path": "a.pfm", "array": rng.random((4, 5))}),
        "write_image": (formats.write_image, {"path": "a.png", "array": rng.random((4, 5))}),
        "write_capture": (formats.write_capture, {"lightfield": lf, "folder": "cap"}),
        "save_lightfield": (formats.save_lightfield, {"lf": lf, "path": "cap"}),
        "save_lightfield h5": (formats.save_lightfield, {"lf": lf, "path": "lf.h5"}),
        "write_lightfield_h5": (hdf5.write_lightfield_h5, {"path": "lf.h5", "lf": lf}),
        "write_cube_h5": (formats.write_cube_h5, {"path": "c.h5", "wavelengths": wl,
                                                  "cube": rng.random((1, 2, 3, 6, 8))}),
        "write_envi": (formats.write_envi, {"path_hdr_or_base": "e.hdr", "wavelengths": wl,
                                            "cube": rng.random((3, 6, 8))}),
        "write_ply": (ply.write_ply, {"path": "p.ply", "points": rng.random((4, 3))}),
        "write_middlebury": (formats.write_middlebury, {"folder": "mb", "pair": pair}),
        "CubeWriter": (hdf5.CubeWriter, {"wavelengths": wl}),
    }
    return {name: (f, lambda f=f, base=base, **kw: (_cube_writer if f is hdf5.CubeWriter
                                                    else f)(**{**base, **kw}))
            for name, (f, base) in calls.items()}


_WRITERS = _writer_calls()
_WRITER_OPTIONS = [(name, p) for name, (f, _) in _WRITERS.items()
                   for p in _keywords(f, leave=("kwargs", "self"))]
_WRITER_OPTIONS += [("save_lightfield", "image_format"), ("save_lightfield h5", "compression"),
                    ("save_lightfield", "compression")]
_WRITER_OPTIONS += [("CubeWriter", p) for p in ("r", "c", "cube_rc", "mask_rc")]


@settings(max_examples=500, deadline=None, derandomize=True)
@given(st.sampled_from(_WRITER_OPTIONS), SAFE_JUNK)
def test_the_writers_take_any_option_or_refuse_it_in_one_line(option, value):
    """Every argument of the writers (a path of ``None``, ``2.5`` or a list, ``bit_depth``,
    ``compression`` or ``image_format`` as an array, ``scale=None``, ``metadata='x'``,
    ``wavelengths={}``, ``scalars=1``, ``comment`` as an array, ``pair=None``, a view
    ``r='x'``, a cube of ``1e300`` and some 270 more were tracebacks or overflows)."""
    _fuzz(_WRITERS, option, value)


@functools.lru_cache(maxsize=1)
def _stage_calls():
    """The stages of completion on a tiny capture, as :func:`_writer_calls`."""
    from hyperlf import completion

    lf = _scene()
    ref = lf.gt_disparity[lf.reference]
    disp = completion.propagate_disparity(lf, ref)
    wl, bidx = completion.band_order(lf)
    cube, mask = completion.register_view(lf, disp, (0, 1), bidx, 0.5)
    folder = tempfile.TemporaryDirectory()  # removed with the cache, at the end of the run
    out = os.path.join(folder.name, "n.h5")
    completion.naive_completion(lf, ref, out_path=out)
    calls = {
        "naive_completion": (completion.naive_completion, {"lf": lf, "ref_disparity": ref}),
        "naive_completion to a file": (completion.naive_completion,
                                       {"lf": lf, "ref_disparity": ref, "out_path": "n.h5"}),
        "propagate_disparity": (completion.propagate_disparity,
                                {"lf": lf, "ref_disparity": ref}),
        "register_view": (completion.register_view, {"lf": lf, "disparities": disp,
                                                     "view": (0, 1), "band_index": bidx}),
        "band_order": (completion.band_order, {"lf": lf}),
        "background_fill": (completion.background_fill,
                            {"disparity": np.array([[1.0, np.nan, 3.0]])}),
        "fill_missing": (completion.fill_missing, {"cube": cube, "mask": mask,
                                                   "wavelengths": wl}),
        "infer_missing": (completion.infer_missing, {"cube": cube, "mask": mask,
                                                     "disparity": disp[0, 1],
                                                     "guide": lf.views[0, 1]}),
        "read_band_mask": (completion.read_band_mask, {"path": out}),
    }
    calls = {name: (f, lambda f=f, base=base, **kw: f(**{**base, **kw}))
             for name, (f, base) in calls.items()}
    return calls, folder


_STAGE_OPTIONS = [(name, p) for name, (f, _) in _stage_calls()[0].items()
                  for p in _keywords(f, leave=("progress",))]


@settings(max_examples=500, deadline=None, derandomize=True)
@given(st.sampled_from(_STAGE_OPTIONS), SAFE_JUNK)
def test_the_completion_stages_take_any_option_or_refuse_it_in_one_line(option, value):
    """The naive baseline, propagation, registration, band order, background fill, spectral
    fill, inference and the masks of a completion file (``fill`` or ``impl`` as an array,
    ``out_path=2.5``, ``lf=None``, ``view=1``, ``band_index={}``, ``occlusion_tol=-1``,
    ``mask=True``, ``sigma_d=1e-300``, ``radius=1e300``, ``view='x'`` and some 140 more were
    tracebacks, numba typing errors, divisions by zero or maps of NaN)."""
    _fuzz(_stage_calls()[0], option, value)


@pytest.mark.parametrize("name, keyword, value, words", [
    ("write_pfm", "path", None, "path must be a path (a non-empty str or os.PathLike), got None"),
    ("write_pfm", "path", ".", "path . is a folder; it must name a file"),
    ("write_pfm", "scale", None, "PFM scale must be a finite number, got None"),
    ("write_image", "bit_depth", np.ones(3), "bit_depth must be one of 8, 16, 32, got array("),
    ("write_capture", "progress", 1, "progress must be True or False, got 1"),
    ("save_lightfield", "compression", "gzip", "unknown key 'compression' in the options of "
                                               "save_lightfield; a capture folder takes "
                                               "image_format"),
    ("write_cube_h5", "metadata", "x", "metadata must be a dict (or None), got str"),
    ("write_ply", "comment", 5, "comment must be one line of ASCII text or None, got 5"),
    ("write_middlebury", "pair", None, "pair must be a StereoPair, got NoneType"),
    ("CubeWriter", "r", "x", "view (r, c) must be 2 integers within (1, 2) (from 0), got ('x', "),
])
def test_the_writers_name_the_argument_and_what_it_takes(name, keyword, value, words,
                                                         tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InvalidInputError) as exc:
        _WRITERS[name][1](**{keyword: value})
    assert str(exc.value).startswith(words)
    assert not any(tmp_path.iterdir())  # refused before any work


@pytest.mark.parametrize("name, keyword, value, words", [
    ("register_view", "view", (2, 0), "view must be 2 integers within (2, 2) (from 0)"),
    ("register_view", "band_index", np.zeros((3, 3)), "band_index must be 2 x 2 integers in "
                                                      "0..3 (from band_order)"),
    ("register_view", "occlusion_tol", -1, "occlusion_tol must be a finite number >= 0 or "
                                           "None"),
    ("infer_missing", "sigma_d", 1e-300, "infer sigma_d must be a finite number in [1e-06, "
                                         "1e+06]"),
    ("infer_missing", "radius", 10 ** 6, "infer radius 1000000 px reaches past the 16 x 12 px "
                                         "view; use at most 16"),
    ("fill_missing", "wavelengths", np.zeros((3, 3)), "wavelengths must have shape (4,)"),
    ("background_fill", "disparity", None, "disparity must be an array of real numbers, got "
                                              "None"),
    ("read_band_mask", "view", "x", "view must be 2 integers within (2, 2)"),
])
def test_the_stages_name_the_argument_and_what_it_takes(name, keyword, value, words):
    with pytest.raises(InvalidInputError) as exc:
        _stage_calls()[0][name][1](**{keyword: value})
    assert str(exc.value).startswith(words)


_DEMO_JUNK = [("seed", "x"), ("seed", 1e300), ("grid", (1, 1)), ("grid", "x"), ("grid", [1]),
              ("size", (0, 5)), ("size", np.zeros((3, 3))), ("metric", None), ("labels", 1e300),
              ("labels", None), ("progress", np.zeros(2)), ("log", 5), ("out_dir", 5)]


@pytest.mark.parametrize("name, value", _DEMO_JUNK)
def test_the_demo_refuses_its_options_in_one_line_before_writing(tmp_path, name, value):
    """``run_demo(grid='x')``, ``size=[1]``, ``labels=1e300``, ``log=5`` and the like were
    TypeErrors and ValueErrors (the survey of the forty-fourth session); nothing is written."""
    from hyperlf.errors import InvalidInputError
    from hyperlf.pipeline import run_demo

    kw = {"grid": (2, 2), "size": (16, 20), "labels": 4, name: value}
    out = kw.pop("out_dir", tmp_path / "demo")
    with pytest.raises(InvalidInputError) as err:
        run_demo(out, **kw)
    assert "\n" not in str(err.value) and not (tmp_path / "demo").exists()


_RUN_JUNK = [("grid", "x"), ("grid", (10 ** 400, 2)), ("board", [1]), ("board", None),
             ("square", "x"), ("mode", np.zeros(2)), ("reference", "x"), ("focal_px", -1),
             ("log", "x"), ("pattern", 5), ("shots", None), ("out_dir", 2.5)]


@pytest.mark.parametrize("name, value", _RUN_JUNK)
def test_calibration_and_ingest_runs_refuse_their_options_in_one_line(tmp_path, name, value):
    """``run_calibration(board=[1])``, ``square='x'``, ``reference='x'``, ``grid=(10**400, 2)``
    and the like were TypeErrors, or a grid of 10**400 cameras being built; ``run_ingest``
    takes the same paths and pattern."""
    from hyperlf.errors import InvalidInputError
    from hyperlf.pipeline import run_calibration, run_ingest

    base = {"shots": tmp_path, "out_dir": tmp_path / "out", "pattern": "cam{index}.png",
            "grid": (3, 3), "board": (8, 6)}
    kw = {**base, name: value}
    with pytest.raises(InvalidInputError) as err:
        run_calibration(kw.pop("shots"), kw.pop("out_dir"), **kw)
    assert "\n" not in str(err.value)
    if name in ("pattern", "out_dir", "log"):
        kw = {"raw": tmp_path, "out_dir": tmp_path / "out", "calibration": tmp_path / "c.toml",
              "pattern": "cam{index}.png", name: value}
        with pytest.raises(InvalidInputError):
            run_ingest(kw.pop("raw"), kw.pop("out_dir"), **kw)


_PICTURE_JUNK = [("save_disparity_png", "cmap", "x"), ("save_disparity_png", "vmin", "x"),
                 ("save_disparity_png", "path", 5), ("save_mosaic_png", "max_side", 0),
                 ("save_mosaic_png", "wavelengths", np.ones(3)), ("save_mosaic_png", "title",
                                                                  np.zeros(2)),
                 ("save_share_mosaic_png", "shares", "x"), ("save_spectrum_plot", "labels", 5),
                 ("save_error_png", "truth", np.zeros((3, 3))), ("save_figure", "fig", None)]


@pytest.mark.parametrize("function, name, value", _PICTURE_JUNK)
def test_pictures_refuse_their_options_in_one_line_and_leave_no_figure_open(tmp_path, function,
                                                                           name, value):
    """``cmap='x'`` (matplotlib's own error), ``max_side=0`` (a division by zero), a path of
    5, ``labels=5``, truth of another shape were tracebacks; a refused write closed no
    figure (matplotlib warned after twenty)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hyperlf import visualise
    from hyperlf.errors import InvalidInputError

    rng = np.random.default_rng(0)
    views, img = rng.random((2, 2, 8, 8)), rng.random((8, 8))
    base = {"save_disparity_png": {"disparity": img},
            "save_mosaic_png": {"views": views, "wavelengths": np.full((2, 2), 500.0)},
            "save_share_mosaic_png": {"shares": views, "title": "t", "label": "l"},
            "save_spectrum_plot": {"wavelengths": np.arange(4.0) + 450,
                                   "spectra": rng.random((2, 4))},
            "save_error_png": {"estimate": img, "truth": img},
            "save_figure": {"fig": plt.figure()}}[function]
    kw = {"path": tmp_path / "p.png", **base, name: value}
    before = len(plt.get_fignums())
    with pytest.raises(InvalidInputError) as err:
        getattr(visualise, function)(**kw)
    assert "\n" not in str(err.value)
    assert len(plt.get_fignums()) <= before and not (tmp_path / "p.png").exists()
    plt.close("all")
