"""Arguments of the input/output helpers fuzzed as in ``test_options``: the readers
(:mod:`hyperlf.formats`), the result sets (:mod:`hyperlf.outputs`), the memory plan
(:mod:`hyperlf.tiling`), the batch (:mod:`hyperlf.batch`), the light-field helpers
(:mod:`hyperlf.lightfield`), the pictures and the report (:mod:`hyperlf.pipeline`,
:mod:`hyperlf.visualise`, :mod:`hyperlf.report`) and the data sets
(:mod:`hyperlf.datasets`). Every argument takes what it documents or is refused with one line
of a hyperlf error before any work, never a ``TypeError``, ``AttributeError``,
``IndexError``, ``OverflowError`` or numpy warning from deep inside; a path that names nothing
is a :class:`DataNotFoundError`. Every file goes into a temporary folder."""

from __future__ import annotations

import atexit
import functools
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyperlf.errors import DataNotFoundError, HyperLFError, InvalidInputError
from test_options import _in_temp_folder, _keywords
from test_options_io import SAFE_JUNK, _fuzz, _scene


@functools.lru_cache(maxsize=1)
def _files() -> Path:
    """A folder of one file of each kind the readers take (removed at exit)."""
    from hyperlf import formats, outputs
    from hyperlf.formats import ply

    root = Path(tempfile.mkdtemp(prefix="hyperlf-api-io-"))
    atexit.register(shutil.rmtree, root, True)
    lf, rng = _scene(), np.random.default_rng(0)
    formats.write_capture(lf, root / "cap")
    formats.write_lightfield_h5(root / "lf.h5", lf)
    formats.write_cube_h5(root / "c.h5", rng.random((1, 2, 3, 6, 8)), [450.0, 550.0, 650.0])
    formats.write_envi(root / "e.hdr", rng.random((3, 6, 8)), [450.0, 550.0, 650.0])
    formats.write_pfm(root / "a.pfm", rng.random((4, 5)).astype(np.float32))
    formats.write_image(root / "a.png", rng.random((4, 5)))
    ply.write_ply(root / "p.ply", rng.random((4, 3)), scalars={"confidence": rng.random(4)})
    formats.write_middlebury(root / "mb", formats.StereoPair(
        left=rng.random((6, 8, 3)), right=rng.random((6, 8, 3)),
        gt_disparity=np.full((6, 8), 2.0), scale=4.0, max_disparity=4))
    hci = root / "hci"
    hci.mkdir()
    for i in range(9):
        formats.write_image(hci / f"input_Cam{i:03d}.png", np.full((6, 7, 3), i, np.uint8))
    formats.write_pfm(hci / "gt_disp_lowres.pfm", rng.normal(size=(6, 7)).astype(np.float32))
    (hci / "parameters.cfg").write_text(
        "[intrinsics]\nfocal_length_mm = 100\n\n[extrinsics]\nnum_cams_x = 3\nnum_cams_y = 3\n"
        "baseline_mm = 90.0\n\n[meta]\ndisp_min = -1.5\ndisp_max = 1.5\nname = fake\n")
    (root / "data" / "hci4d" / "antinous").mkdir(parents=True)
    with outputs.result_folder(root / "batch" / "cap", command="depth") as stage:
        formats.write_pfm(stage / "disparity.pfm", np.zeros((12, 16), np.float32))
    return root


def _with(f, **base):
    return f, lambda **kw: f(**{**base, **kw})


def _result_folder(**kw):
    from hyperlf.outputs import result_folder

    with result_folder(**{"folder": "rf", **kw}) as stage:
        (stage / "f.txt").write_text("x")


def _result_files(**kw):
    from hyperlf.outputs import result_files

    with result_files(**{"paths": ["a.txt", "b.txt"], **kw}) as staged:
        for p in staged:
            p.write_text("x")


def _block_mean_cube(cube, factor=2, view=(0, 1)):
    from hyperlf.lightfield import BlockMeanCube

    return BlockMeanCube(cube, factor)[view]


def _write_view_extra(name="extra", r=0, c=0, data=None):
    from hyperlf.formats import CubeWriter

    with CubeWriter("w.h5", (1, 2, 3, 6, 8), [450.0, 550.0, 650.0]) as w:
        w.write_view(0, 0, np.ones((3, 6, 8)))
        w.write_view(0, 1, np.ones((3, 6, 8)))
        w.write_view_extra(name, r, c, np.ones((6, 8)) if data is None else data)


@functools.lru_cache(maxsize=1)
def _calls() -> dict:
    """Each function with one valid call, as ``name -> (function, call)``; the fuzzers set
    one keyword."""
    from hyperlf import batch, datasets, formats, lightfield, outputs, pipeline, report, tiling
    from hyperlf import visualise
    from hyperlf.formats import capture, envi, hci, hdf5, images, middlebury, patterns, pfm, ply

    root, lf, rng = _files(), _scene(), np.random.default_rng(0)
    K = [[100.0, 0, 8], [0, 100.0, 6], [0, 0, 1]]
    metric_lf = lf.replace(metadata={"calibration": {"mode": "full", "camera_matrix": K,
                                                     "baseline": 40.0}})
    d, conf, png = np.full((12, 16), 1.0), np.full((12, 16), 0.5), str(root / "a.png")
    task = batch.CaptureTask(name="cap", capture=str(root / "cap"),
                             output=str(root / "batch" / "cap"))
    row = batch.CaptureResult("cap", str(root / "cap"), "done", 1.0)
    pair = {"left": rng.random((6, 8, 3)), "right": rng.random((6, 8, 3)),
            "gt_disparity": np.full((6, 8), 2.0), "scale": 4.0, "max_disparity": 4}
    sig = lightfield.capture_signature(lf)
    return {
        "data_root": _with(datasets.data_root, root=str(root / "data")),
        "dataset_path": _with(datasets.dataset_path, name="antinous", root=str(root / "data")),
        "has_data": _with(datasets.has_data, name="antinous"),
        "expand_user": _with(datasets.expand_user, path="data/x.csv"),
        "save_metric_outputs": _with(pipeline.save_metric_outputs, out="m", disparity=d,
                                     lf=metric_lf, confidence=conf, min_confidence=0.1),
        "write_lightfield_pictures": _with(pipeline.write_lightfield_pictures, lf=lf, out="p",
                                           stem="s_"),
        "save_disparity_outputs": _with(pipeline.save_disparity_outputs, out="d", disparity=d,
                                        title="t", truth=d + 0.1, confidence=conf,
                                        stem="disp", unit="px"),
        "finite_range": _with(pipeline.finite_range, values=np.array([np.nan, -1.5, 2.0])),
        "display_step": _with(visualise.display_step, rows=100, cols=200, max_side=50),
        "false_colour": _with(visualise.false_colour, views=lf.views,
                              wavelengths=lf.wavelengths),
        "wavelength_to_rgb": _with(visualise.wavelength_to_rgb, wavelengths=[450.0, 650.0]),
        "result_folder": (outputs.result_folder, _result_folder),
        "result_files": (outputs.result_files, _result_files),
        "manifest_files": _with(outputs.manifest_files, folder=str(root / "batch" / "cap")),
        "read_manifest": _with(outputs.read_manifest, folder=str(root / "batch" / "cap")),
        "foreign_entries": _with(outputs.foreign_entries, folder=str(root / "batch" / "cap")),
        "check_replaceable": _with(outputs.check_replaceable, target="new", overwrite=False),
        "clean_stale": _with(outputs.clean_stale, folder="."),
        "parse_memory": _with(tiling.parse_memory, text="6G"),
        "format_memory": _with(tiling.format_memory, nbytes=3 * 2 ** 30),
        "check_memory": _with(tiling.check_memory, nbytes=100, what="a", remedy="b"),
        "check_label_volume": _with(tiling.check_label_volume, n_labels=8, shape=(12, 16)),
        "check_strips": _with(tiling.check_strips, strips=[(0, 32), (32, 40)], height=40),
        "row_strips": _with(tiling.row_strips, height=70, rows=32),
        "depth_memory": _with(tiling.depth_memory, shape=(64, 80), n_labels=16, n_views=4,
                              strip_rows=16, selection=True),
        "plan": _with(tiling.plan, shape=(384, 512), n_labels=64, n_views=30,
                      max_memory=640 * 2 ** 20, selection=False, tile_rows=None),
        "CaptureTask": _with(batch.CaptureTask, name="c", capture="cap", output="o",
                             depth_args=(), overwrite=False, disparity_range=(-1.0, 1.0),
                             downscale=1),
        "find_captures": _with(batch.find_captures, inputs=[str(root / "cap")]),
        "plan_batch": _with(batch.plan_batch, inputs=[str(root / "cap")], out="b",
                            depth_args=["--labels=8"], disparity_range=(-1.0, 1.0),
                            downscale=1, overwrite=False),
        "run_capture": _with(batch.run_capture, task=task),
        "run_batch": _with(batch.run_batch, tasks=[task], workers=1, scheduler=None,
                           progress=False),
        "write_summary": _with(batch.write_summary, out="s", rows=[row]),
        "finish_batch": _with(batch.finish_batch, out="f", rows=[row]),
        "raster_wavelengths": _with(lightfield.raster_wavelengths, rows=2, cols=3,
                                    lambda_min=410.0, lambda_max=700.0, order="raster",
                                    seed=0),
        "filter_layout": _with(lightfield.filter_layout, rows=2, cols=3, order="random",
                               seed=0),
        "view_offsets": _with(lightfield.view_offsets, positions=lf.positions,
                              reference=(0, 1)),
        "grid_positions": _with(lightfield.grid_positions, rows=2, cols=3),
        "centre_view": _with(lightfield.centre_view, rows=5, cols=6),
        "check_disparity_range": _with(lightfield.check_disparity_range,
                                       disparity_range=(-2, 2)),
        "resolve_disparity_range": _with(lightfield.resolve_disparity_range, lf=lf,
                                         disparity_range=(-2, 2)),
        "check_disparity_reach": _with(lightfield.check_disparity_reach,
                                       disparities=(-2.0, 2.0), offsets=lf.offsets,
                                       image_shape=(12, 16)),
        "downscale": _with(lightfield.downscale, lf=lf, factor=2, truth=True),
        "downscale_disparity": _with(lightfield.downscale_disparity, disparity=d, factor=2),
        "BlockMeanCube": _with(_block_mean_cube, cube=lf.gt_cube, factor=2, view=(0, 1)),
        "capture_signature": _with(lightfield.capture_signature, lf=lf),
        "signature_mismatch": _with(lightfield.signature_mismatch, recorded=sig, sig=sig),
        "Section": _with(report.Section, title="t", text="x", table=[("a",), ("1",)],
                         pictures=[(png, "c")]),
        "write_html_report": _with(report.write_html_report, path="r.html", title="t",
                                   sections=[report.Section("a", "x", [("a",), ("1",)],
                                                            [(png, "c")])], footer="f"),
        "load_lightfield": _with(formats.load_lightfield, path=str(root / "cap"), cube=True),
        "open_gt_cube": _with(formats.open_gt_cube, path=str(root / "lf.h5")),
        "describe": _with(formats.describe, path=str(root / "cap")),
        "read_pfm": _with(pfm.read_pfm, path=str(root / "a.pfm")),
        "describe_pfm": _with(pfm.describe_pfm, path=str(root / "a.pfm")),
        "read_image": _with(images.read_image, path=png, as_float=True, channels=None),
        "read_images_same_size": _with(images.read_images_same_size, paths=[png, png],
                                       read=images.read_image, where="here",
                                       labels=["a", "b"]),
        "to_grey": _with(images.to_grey, rgb=rng.random((4, 5, 3))),
        "read_hci_scene": _with(hci.read_hci_scene, folder=str(root / "hci"), grid=None,
                                rows=[0, 1], cols=[1, 2], disparity_margin=0.5),
        "is_hci_scene": _with(hci.is_hci_scene, folder=str(root / "hci")),
        "StereoPair": _with(middlebury.StereoPair, **pair, masks={}, name="n", metadata={}),
        "eval_mask": _with(lambda name="all": middlebury.StereoPair(**pair).eval_mask(name)),
        "read_middlebury": _with(middlebury.read_middlebury, folder=str(root / "mb"),
                                 scale=None),
        "read_capture": _with(capture.read_capture, folder=str(root / "cap"), cube=True),
        "is_capture": _with(capture.is_capture, folder=str(root / "cap")),
        "gt_cube_file": _with(capture.gt_cube_file, folder=str(root / "cap")),
        "read_lightfield_h5": _with(hdf5.read_lightfield_h5, path=str(root / "lf.h5"),
                                    cube=True),
        "open_lightfield_gt_cube": _with(hdf5.open_lightfield_gt_cube,
                                         path=str(root / "lf.h5")),
        "read_cube_h5": _with(hdf5.read_cube_h5, path=str(root / "c.h5")),
        "CubeFile": _with(lambda path: hdf5.CubeFile(path).close(), path=str(root / "c.h5")),
        "open_cube_h5": _with(lambda path: hdf5.open_cube_h5(path).close(),
                              path=str(root / "c.h5")),
        "write_view_extra": _with(_write_view_extra, name="extra", r=0, c=0, data=None),
        "read_envi": _with(envi.read_envi, path=str(root / "e.hdr")),
        "pattern_fields": _with(patterns.pattern_fields, pattern="cam_{r}_{c}.png",
                                allowed=("r", "c"), what="pattern"),
        "expand_pattern": _with(patterns.expand_pattern, pattern="cam_{r}_{c}.png",
                                allowed=("r", "c"), what="pattern", r=1, c=2),
        "read_ply": _with(ply.read_ply, path=str(root / "p.ply")),
        "read_ply_properties": _with(ply.read_ply_properties, path=str(root / "p.ply")),
        "describe_ply": _with(ply.describe_ply, path=str(root / "p.ply")),
    }


def _options() -> list[tuple[str, str]]:
    """Every (function, keyword) pair to fuzz."""
    import inspect

    out = [("expand_pattern", "r"), ("expand_pattern", "c")]
    for name, (f, call) in _calls().items():
        keywords = _keywords(f, leave=("kwargs", "values", "self"))
        if name in ("result_folder", "result_files"):
            keywords = [p for p in inspect.signature(f).parameters]
        out += [(name, p) for p in keywords]
    return out


_OPTION_LIST = _options()


def test_every_valid_call_works():
    for name, (_, call) in _calls().items():
        with _in_temp_folder():
            call()


@settings(max_examples=1500, deadline=None, derandomize=True)
@given(st.sampled_from(_OPTION_LIST), SAFE_JUNK)
def test_the_io_helpers_take_any_argument_or_refuse_it_in_one_line(option, value):
    """Every argument of the readers, result sets, memory plan, batch, light-field helpers,
    pictures and report (a path of ``None`` or ``2.5`` to any reader, ``lf=None`` to the
    pictures, ``shape='x'`` or ``n_labels=None`` to the memory plan, ``cols={}`` to the
    grids, ``provenance='x'`` to a result folder, ``inputs=None`` to a batch, ``scale=1e-300``
    to a Middlebury pair and some 1 350 more were tracebacks, numpy warnings or NaN kept in
    a result)."""
    _fuzz(_calls(), option, value)


def _refusal(name: str, keyword: str, value):
    with _in_temp_folder() as folder:
        with pytest.raises(HyperLFError) as err:
            _calls()[name][1](**{keyword: value})
        assert "\n" not in str(err.value) and not any(folder.iterdir())
    return err.value


@pytest.mark.parametrize("name, keyword, value, words", [
    ("read_pfm", "path", None, "path must be a path (a non-empty str or os.PathLike), got None"),
    ("read_capture", "folder", 2.5, "folder must be a path"),
    ("read_capture", "cube", np.zeros(3), "cube must be True or False"),
    ("read_image", "channels", np.zeros(3), "channels must be one of None, grey, rgb"),
    ("save_metric_outputs", "lf", None, "lf must be a hyperlf.LightField, got NoneType"),
    ("save_metric_outputs", "disparity", np.zeros(3), "disparity must be shape (12, 16)"),
    ("save_disparity_outputs", "stem", 10 ** 400, "stem must be printable text (a str), "
                                                  "got 1000"),
    ("save_disparity_outputs", "title", "\x1f", "title must be printable text (a str)"),
    ("write_lightfield_pictures", "lf", "x", "lf must be a hyperlf.LightField, got str"),
    ("finite_range", "values", "x", "values must be an array of real numbers, got 'x'"),
    ("false_colour", "views", 1e300, "views must be finite images (..., H, W), got 1e+300"),
    ("result_folder", "provenance", "x", "provenance must be a dict (or None), got str"),
    ("result_files", "paths", {}, "paths must be a path or a list of at least one path"),
    ("depth_memory", "n_labels", None, "n_labels must be an integer in 1..9007199254740992"),
    ("plan", "shape", "x", "shape must be (H, W) in 1..2147483648, got 'x'"),
    ("check_label_volume", "shape", None, "shape must be an image size (..., H, W), got None"),
    ("format_memory", "nbytes", 10 ** 400, "nbytes must be a finite number >= 0"),
    ("centre_view", "rows", float("nan"), "rows must be an integer >= 1, got nan"),
    ("filter_layout", "order", {}, "order must be an array of real numbers, got {}"),
    ("view_offsets", "reference", "x", "reference must be 2 integers within (2, 2) (from 0)"),
    ("BlockMeanCube", "factor", 0, "factor must be an integer >= 1, got 0"),
    ("BlockMeanCube", "view", None, "view must be 2 integers within (2, 2) (from 0)"),
    ("plan_batch", "depth_args", None, "depth_args must be a list of text"),
    ("write_summary", "rows", None, "rows must be a list of hyperlf.batch.CaptureResult"),
    ("run_capture", "task", None, "task must be a hyperlf.batch.CaptureTask, got NoneType"),
    ("read_middlebury", "scale", 1e-300, "scale must be a finite number in [1e-06, 1e+06] or "
                                         "None"),
    ("StereoPair", "max_disparity", float("inf"), "max_disparity must be an integer >= 0"),
    ("expand_pattern", "pattern", None, "pattern must be a file name pattern (text), got None"),
    ("expand_pattern", "r", "x", "r must be an integer"),
    ("write_html_report", "sections", [1], "sections must be a list of hyperlf.report.Section"),
    ("Section", "pictures", [("missing.png", 5)], "caption must be text (a str), got 5"),
    # checked whether the scene's parameters.cfg makes it needless or not ('x' was a
    # TypeError on a scene without one)
    ("read_hci_scene", "disparity_margin", "x", "disparity_margin must be a finite number in "
                                                "[0, 1000], got 'x'"),
])
def test_former_failures_name_the_argument_and_what_it_takes(name, keyword, value, words):
    err = _refusal(name, keyword, value)
    assert isinstance(err, InvalidInputError) and str(err).startswith(words), str(err)


@pytest.mark.parametrize("name, keyword", [
    ("read_ply", "path"), ("read_ply_properties", "path"), ("foreign_entries", "folder"),
    ("read_pfm", "path"), ("read_envi", "path"), ("read_cube_h5", "path"),
    ("load_lightfield", "path"), ("read_middlebury", "folder")])
def test_a_path_that_names_nothing_is_data_not_found(name, keyword):
    """``read_ply('x')`` and ``foreign_entries('x')`` were FileNotFoundErrors."""
    assert isinstance(_refusal(name, keyword, "x"), DataNotFoundError)


def test_a_report_with_a_missing_picture_is_refused_before_writing(tmp_path):
    from hyperlf.report import Section, write_html_report

    with pytest.raises(DataNotFoundError, match="picture .*gone.png not found"):
        write_html_report(tmp_path / "r.html", "t", [Section("a", pictures=[(tmp_path /
                                                                              "gone.png", "c")])])
    assert not any(tmp_path.iterdir())


def test_integral_options_are_kept_as_ints():
    from hyperlf import batch, tiling
    from hyperlf.formats import StereoPair

    task = batch.CaptureTask("c", "cap", "o", downscale=2.0, disparity_range=[-1, 1])
    assert type(task.downscale) is int and task.disparity_range == (-1.0, 1.0)
    pair = StereoPair(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)), max_disparity=4.0)
    assert type(pair.max_disparity) is int
    assert tiling.plan((64, 64), 8.0, 4.0, None) == [(0, 64)]


def test_a_numpy_byte_count_beyond_the_memory_is_refused_in_one_line(monkeypatch):
    """``check_memory(np.float32(2.4e10), ...)`` compared the float32 with ``2 ** 1000`` for its
    message: a numpy overflow warning (the random fuzzer's find)."""
    import warnings

    from hyperlf import tiling

    monkeypatch.setattr(tiling, "available_memory", lambda: 1000)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for nbytes in (np.float32(2.4e10), np.int64(2 ** 62), 10 ** 400):
            with pytest.raises(InvalidInputError, match="^a would need about .* GiB of memory"):
                tiling.check_memory(nbytes, "a", "b")
