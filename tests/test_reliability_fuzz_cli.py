"""Hypothesis fuzzing of the command line's option values (issue 10: "CLI option values (long
and format-pattern strings, NaN/inf, huge numbers)").

Every subcommand runs in-process (``hyperlf.cli.main(argv)``) on tiny inputs with one option
given a hostile value: NaN, inf, huge or negative numbers, empty, very long, unicode and
format-pattern strings, comma lists of the wrong length, NUL bytes. For every example:

* nothing but ``SystemExit`` escapes ``main``; the exit code is one of the documented 0, 2, 3, 4
  (1, "other hyperlf error", never turned out to be the right answer for an option value);
* stderr holds no traceback, and a failure is exactly one line (``-q`` silences progress) with
  no Python warning beside it, and leaves nothing behind in its output folder;
* a success really wrote its outputs; no example touches the shared inputs;
* a refusal comes before long work starts (the first step of a progress bar or a call of the
  solver, ``conftest.long_work_seen``), not after minutes of work.

Each example writes into a fresh folder, so no output is ever reused. Numbers that would be
valid and expensive (many labels, large grids) are drawn either small or astronomically large
(refused by the memory checks), so the default run stays fast; ``-m slow`` runs every fuzzer
with many more examples. The bugs the fuzzers found are fixed; their minimal reproducers stay
at the end (``FOUND_BY_FUZZING``) as regression tests.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
import uuid
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hyperlf.cli import main

from conftest import LongWork, long_work_seen, long_work_stopped

SRC = str(Path(__file__).resolve().parents[1] / "src")
EXIT_CODES = {0, 2, 3, 4}
MAX_SECONDS = 20.0  # one example that runs longer counts as a hang

_HEALTH = [HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
           HealthCheck.filter_too_much, HealthCheck.data_too_large]
# the default run draws the same examples every time (CI stays reproducible); -m slow explores
FUZZ = settings(max_examples=6, deadline=None, suppress_health_check=_HEALTH,
                derandomize=True)
FUZZ_HEAVY = settings(max_examples=150, deadline=None, suppress_health_check=_HEALTH)


# ----------------------------------------------------------------------------- strategies
FORMAT_PATTERNS = ["{", "}", "{}", "{0}", "{{}}", "%s", "%d", "%n", "%(x)s", "{col.foo}",
                   "{row[0]}", "{index:>999999}", "{row:99999999}", "{!r}", "${HOME}", "$(id)",
                   "`id`", "~", "*", "?", "[a-z]", "\\", "'", '"', "-", "-h", "--help",
                   ".", "..."]
ODD_NUMBERS = ["nan", "NaN", "-nan", "inf", "-inf", "Infinity", "+inf", "1e400", "-1e400",
               "1e308", "-1e308", "5e-324", "0", "-0", "0.0", "-1", "-2", "-1e9", "1e9",
               "1e18", "99999999999999999999999999", "-99999999999999999999", "0x10", "1_000",
               " 3 ", "", " ", "1.5", "2.0", "\u00bd", "\u0661\u0662", "3e", "e3", "+", "None",
               "True", "0b1", "1j"]
COMMA_LISTS = ["1,", ",", ",,", "1,2,3,4", "1,,2", "1,2,", ",1,2", "1x", "x", "1x2x3", "x2",
               "nan,nan", "inf,1", "1,nan", "-inf,inf", "-1,-1", "0,0", "5,6,", " 1, 2", "1;2",
               "1 2", "1.5,2.5", "1e400,1", "2,1", "1,1"]


def _long_text(min_size=256, max_size=4000, *, component=None):
    """Long strings made by repeating a short (possibly unicode) piece; with ``component``,
    a '/' every ``component`` characters (no single name longer: FOUND_BY_FUZZING)."""
    def make(piece, n):
        text = (piece * n)[:n]
        if component:
            text = "/".join(text[i:i + component] for i in range(0, len(text), component))
        return text
    return st.builds(make, st.text(min_size=1, max_size=6), st.integers(min_size, max_size))


#: Text without lone surrogates (a str argv cannot carry a non-UTF-8 name; the subprocess test
#: at the end passes one as bytes).
_BAD = ""
PLAIN_TEXT = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters=_BAD),
                     max_size=40)
HOSTILE_TEXT = st.one_of(st.sampled_from(FORMAT_PATTERNS + ODD_NUMBERS + COMMA_LISTS),
                         PLAIN_TEXT, _long_text(256, 1000, component=None).filter(
                             lambda s: not any(c in s for c in _BAD)))


def numbers(*, small=(-3, 8), huge=None):
    """Number-like strings: odd spellings, floats of every kind, integers either in ``small``
    or beyond ``huge`` (a value that big must be refused, never attempted)."""
    ints = st.integers(*small)
    if huge is not None:
        ints = st.one_of(ints, st.integers(huge, 10**40), st.integers(-10**40, -huge))
    return st.one_of(st.sampled_from(ODD_NUMBERS), ints.map(str),
                     st.floats(allow_nan=True, allow_infinity=True).map(repr), HOSTILE_TEXT)


def lists_of(item, *, max_size=4, seps=(",",)):
    """Comma lists of ``item`` strings, of any length (the right one included)."""
    return st.one_of(st.sampled_from(COMMA_LISTS),
                     st.builds(lambda parts, sep: sep.join(parts),
                               st.lists(item, min_size=0, max_size=max_size),
                               st.sampled_from(seps)))


def names_or(valid, *, extra=()):
    """An option that takes a name: a valid one, a near miss, or hostile text."""
    valid = list(valid)
    near = [v.upper() for v in valid] + [v + "x" for v in valid] + [v[:2] for v in valid]
    return st.one_of(st.sampled_from(valid + list(extra)), st.sampled_from(near), HOSTILE_TEXT)


SUFFIXES = ["", ".h5", ".hdf5", ".H5", ".png", ".PNG", ".pfm", ".tif", ".tiff", ".hdr", ".img",
            ".csv", ".jpg", ".toml", ".h5.png", ".", ".partial", ".scratch"]


def _safe_name(text: str) -> str:
    """A name that stays inside its example's folder (no absolute path, no '..')."""
    parts = [p for p in text.replace("\\", "/").split("/") if p not in ("", ".", "..")]
    return "/".join(parts) or "out"


OUTPUT_NAMES = st.builds(lambda stem, suffix: _safe_name(stem) + suffix,
                         st.one_of(st.sampled_from(FORMAT_PATTERNS + ["out", "a b", "-o", "é",
                                                                      "x" * 255, "x" * 256,
                                                                      "é" * 128, "a/b/c"]),
                                   PLAIN_TEXT, _long_text(200, 600).filter(
                                       lambda s: not any(c in s for c in _BAD))),
                         st.sampled_from(SUFFIXES))
PICTURE_NAMES = st.builds(lambda stem, suffix: _safe_name(stem) + suffix, PLAIN_TEXT,
                          st.sampled_from(["", ".png", ".PNG", ".jpg", ".tif", ".pdf", ".svg",
                                           ".h5", ".csv", ".x"]))
SMALL_LABELS = numbers(small=(-2, 8), huge=10**9)


# ----------------------------------------------------------------------------- fixtures
@dataclass
class World:
    """The tiny shared inputs and the folder every example's output goes under."""
    cap: Path      # 2 x 2 capture, 32 x 40 px, ground-truth disparity and cube
    h5: Path       # the same light field as .h5
    cube: Path     # its cube file (gt_cube.h5)
    pfm: Path      # a 32 x 40 disparity PFM
    left: Path     # a 16-bit stereo pair, 24 x 32 px, right = left shifted by 3 px
    right: Path
    weights: Path  # a good weights file for --profile weights:
    outputs: Path
    shots: Path    # board shots of a 1 x 3 synthetic array, Cam-{index}.png, 160 x 120 px
    cal: Path      # its calibration folder (calibration.toml)
    scene: Path    # a Middlebury v2 scene folder of the stereo pair, ground truth 3 px

    def fresh(self) -> Path:
        """A new, empty folder for one example."""
        d = self.outputs / uuid.uuid4().hex
        d.mkdir()
        return d

    def inputs(self) -> list:
        """Every input file with its size and mtime (to prove nothing touched them)."""
        root = self.cap.parent
        return sorted((str(p), p.stat().st_size, p.stat().st_mtime_ns)
                      for p in root.rglob("*"))


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> World:
    from hyperlf import synthesis
    from hyperlf.formats import save_lightfield, write_image, write_pfm

    root = tmp_path_factory.mktemp("fuzz-in")
    lf = synthesis.procedural_scene(**dict(synthesis.SCENES["planes"], rows=2, cols=2,
                                           height=32, width=40))
    save_lightfield(lf, root / "cap")
    save_lightfield(lf, root / "lf.h5")
    tex = np.random.default_rng(0).random((24, 40)).astype(np.float32)
    write_image(root / "l.png", tex[:, 2:34], bit_depth=16)
    write_image(root / "r.png", tex[:, 5:37], bit_depth=16)
    write_pfm(root / "d.pfm", np.zeros((32, 40), np.float32))
    n_bands = len(lf.cube_wavelengths)
    (root / "w.csv").write_text(",".join(["1"] * n_bands))
    from hyperlf.calibration.rig import make_rig

    rig = make_rig(1, 3, seed=3, imperfect=0.5, image_size=(160, 120), focal=150.0)
    (root / "shots").mkdir()
    for (r, c), img in rig.render(rig.board_pose(300.0), supersample=1).items():
        write_image(root / "shots" / f"Cam-{c}.png", np.clip(img, 0, 1), bit_depth=16)
    assert main(["-q", "calibrate", str(root / "shots"), "--pattern=Cam-{index}.png",
                 "--grid=1,3", f"--board={rig.board.cols},{rig.board.rows}",
                 "--focal-px=150", "-o", str(root / "cal")]) == 0
    from hyperlf.formats import StereoPair, write_middlebury

    pair = np.repeat(tex[..., None], 3, axis=2)
    write_middlebury(root / "scene", StereoPair(
        left=pair[:, 2:34], right=pair[:, 5:37], gt_disparity=np.full((24, 32), 3.0, np.float32),
        scale=8.0, max_disparity=6))
    return World(cap=root / "cap", h5=root / "lf.h5", cube=root / "cap" / "gt_cube.h5",
                 pfm=root / "d.pfm", left=root / "l.png", right=root / "r.png",
                 weights=root / "w.csv", outputs=tmp_path_factory.mktemp("fuzz-out"),
                 shots=root / "shots", cal=root / "cal", scene=root / "scene")


# ----------------------------------------------------------------------------- running
@dataclass
class Run:
    argv: list
    code: int
    out: str
    err: str
    seconds: float
    warnings: list


def run_main(argv, capfd) -> Run:
    """``hyperlf -q ARGV`` in-process; SystemExit's code is the exit code."""
    argv = [str(a) for a in argv]
    capfd.readouterr()
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            code = main(["-q", *argv])
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    out, err = capfd.readouterr()
    return Run(argv, code, out, err, time.perf_counter() - t0,
               [f"{w.category.__name__}: {w.message}" for w in caught])


def check(run: Run, folder: Path | None, written=None) -> None:
    """The properties every example must have (see the module docstring)."""
    where = f"argv={run.argv!r}\nstderr={run.err[-3000:]}"
    assert run.code in EXIT_CODES, f"exit {run.code}\n{where}"
    assert "Traceback" not in run.err, where
    assert run.seconds < MAX_SECONDS, f"took {run.seconds:.1f} s\n{where}"
    if run.code != 0:
        message = run.err.strip()
        assert "\n" not in message and message.startswith("hyperlf"), where
        assert not run.warnings, f"{run.warnings}\n{where}"
        if folder is not None:
            left = sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))
            assert left == [], f"a failed run left {left}\n{where}"
    elif written is not None:
        assert written(), f"exit 0 but the outputs are missing\n{where}"


def _has(path: Path, *names) -> bool:
    return path.is_dir() and all((path / n).is_file() for n in names)


def _any_file(path: Path, pattern="*") -> bool:
    return path.is_dir() and any(p.is_file() for p in path.glob(pattern))


def _lightfield_written(out: Path) -> bool:
    if out.suffix.lower() in (".h5", ".hdf5"):
        return out.is_file() and out.stat().st_size > 0
    return _has(out, "capture.toml")


# ----------------------------------------------------------------------------- cases
# Each case: (strategy of the hostile value, argv(world, value, out), outputs written on exit 0).
# The value always travels as --option=VALUE so that a value starting with '-' is a value.
#: Placeholders a value may be, for an existing input of the wrong (or right) kind.
_INPUTS = {"@pfm": "pfm", "@left": "left", "@cap": "cap", "@cube": "cube", "@h5": "h5",
           "@scene": "scene"}


def _input(world: World, value: str) -> str:
    return str(getattr(world, _INPUTS[value])) if value in _INPUTS else value


INPUT_TEXT = st.one_of(HOSTILE_TEXT, st.sampled_from(list(_INPUTS)))


CASES = {
    # --- synth procedural: sizes and grids small or astronomically large (memory check)
    "synth-size": (lists_of(numbers(small=(-1, 24), huge=10**12), seps=(",", "x", "X")),
                   lambda w, v, o: ["synth", "procedural", f"--size={v}", "--grid=2,2",
                                    "--no-pictures", "-o", o], _lightfield_written),
    "synth-grid": (lists_of(numbers(small=(-1, 3), huge=10**6), seps=(",", "x")),
                   lambda w, v, o: ["synth", "procedural", "--size=12,16", f"--grid={v}",
                                    "--no-pictures", "-o", o], _lightfield_written),
    "synth-bands": (lists_of(numbers(small=(-5, 2000))),
                    lambda w, v, o: ["synth", "procedural", "--size=12,16", "--grid=2,2",
                                     f"--bands={v}", "--no-pictures", "-o", o],
                    _lightfield_written),
    "synth-layout": (st.one_of(names_or(["raster", "serpentine", "random"]),
                               lists_of(numbers(small=(-2, 5)), max_size=6)),
                     lambda w, v, o: ["synth", "procedural", "--size=12,16", "--grid=2,2",
                                      f"--layout={v}", "--no-pictures", "-o", o],
                     _lightfield_written),
    "synth-noise": (numbers(small=(-2, 3)),
                    lambda w, v, o: ["synth", "procedural", "--size=12,16", "--grid=2,2",
                                     f"--noise={v}", "--no-pictures", "-o", o],
                    _lightfield_written),
    "synth-seed": (numbers(small=(-3, 10**6), huge=10**20),
                   lambda w, v, o: ["synth", "procedural", "--size=12,16", "--grid=2,2",
                                    f"--seed={v}", "--no-pictures", "-o", o],
                   _lightfield_written),
    "synth-scene": (names_or(["planes", "slanted", "occlusion", "solids", "rings"]),
                    lambda w, v, o: ["synth", "procedural", "--size=12,16", "--grid=2,2",
                                     f"--scene={v}", "--no-pictures", "-o", o],
                    _lightfield_written),
    "synth-bit-depth": (numbers(small=(0, 33)),
                        lambda w, v, o: ["synth", "procedural", "--size=12,16", "--grid=2,2",
                                         f"--bit-depth={v}", "--no-pictures", "-o", o],
                        _lightfield_written),
    "synth-output": (OUTPUT_NAMES,
                     lambda w, v, o: ["synth", "procedural", "--size=12,16", "--grid=2,2",
                                      "--no-pictures", f"--output={o}/{v}"], None),
    "synth-hci-scene": (INPUT_TEXT,
                        lambda w, v, o: ["synth", "hci", "-o", o, "--", _input(w, v)], None),
    # --- convert
    "convert-output": (OUTPUT_NAMES,
                       lambda w, v, o: ["convert", w.cap, f"--output={o}/{v}"], None),
    "convert-pfm-output": (OUTPUT_NAMES,
                           lambda w, v, o: ["convert", w.pfm, f"--output={o}/{v}"], None),
    "convert-input": (INPUT_TEXT,
                      lambda w, v, o: ["convert", "-o", o / "x.h5", "--", _input(w, v)], None),
    "convert-view": (lists_of(numbers(small=(-2, 3), huge=10**9)),
                     lambda w, v, o: ["convert", w.cube, f"--view={v}", "-o", o / "c.hdr"],
                     None),
    "convert-bit-depth": (numbers(small=(0, 33)),
                          lambda w, v, o: ["convert", w.h5, f"--bit-depth={v}", "-o", o / "c"],
                          None),
    # --- demo (about 1 s when valid): grids and sizes small or astronomically large
    "demo-grid": (lists_of(numbers(small=(0, 3), huge=10**6)),
                  lambda w, v, o: ["demo", "--size=12,16", f"--grid={v}", "--labels=2",
                                   "--metric=ncc", "-o", o / "d"], None),
    "demo-size": (lists_of(numbers(small=(-1, 16), huge=10**12)),
                  lambda w, v, o: ["demo", f"--size={v}", "--grid=2,2", "--labels=2",
                                   "--metric=ncc", "-o", o / "d"], None),
    "demo-labels": (SMALL_LABELS,
                    lambda w, v, o: ["demo", "--size=12,16", "--grid=2,2", f"--labels={v}",
                                     "--metric=ncc", "-o", o / "d"], None),
    "demo-seed": (numbers(small=(-3, 10**6), huge=10**20),
                  lambda w, v, o: ["demo", "--size=12,16", "--grid=2,2", "--labels=2",
                                   "--metric=ncc", f"--seed={v}", "-o", o / "d"], None),
    "demo-metric": (names_or(["ncc", "rsncc", "census", "auto", "census-rsncc"],
                             extra=["ssd"]),
                    lambda w, v, o: ["demo", "--size=12,16", "--grid=2,2", "--labels=2",
                                     f"--metric={v}", "-o", o / "d"], None),
    # --- stereo
    "stereo-range": (lists_of(numbers(small=(-40, 40))),
                     lambda w, v, o: ["stereo", w.left, w.right, f"--disparity-range={v}",
                                      "--optimizer=wta", "-o", o / "s"], None),
    "stereo-channel": (lists_of(numbers(small=(-1, 4), huge=10**9)),
                       lambda w, v, o: ["stereo", w.left, w.right, "--disparity-range=0,4",
                                        f"--channel={v}", "-o", o / "s"], None),
    "stereo-metric": (names_or(["ncc", "rsncc", "census", "ssd", "auto"]),
                      lambda w, v, o: ["stereo", w.left, w.right, "--disparity-range=0,4",
                                       f"--metric={v}", "--optimizer=wta", "-o", o / "s"],
                      None),
    "stereo-optimizer": (names_or(["graphcut", "sgm", "wta"]),
                         lambda w, v, o: ["stereo", w.left, w.right, "--disparity-range=0,4",
                                          "--metric=ncc", f"--optimizer={v}", "-o", o / "s"],
                         None),
    "stereo-aggregation": (names_or(["none", "guided"]),
                           lambda w, v, o: ["stereo", w.left, w.right, "--disparity-range=0,4",
                                            "--metric=ncc", "--optimizer=wta",
                                            f"--aggregation={v}", "-o", o / "s"], None),
    "stereo-aggregation-radius": (numbers(small=(-3, 70), huge=10**9),
                                  lambda w, v, o: ["stereo", w.left, w.right,
                                                   "--disparity-range=0,4", "--metric=ncc",
                                                   "--optimizer=wta", "--aggregation=guided",
                                                   f"--aggregation-radius={v}", "-o", o / "s"],
                                  None),
    "stereo-aggregation-eps": (numbers(small=(-1, 200)),
                               lambda w, v, o: ["stereo", w.left, w.right,
                                                "--disparity-range=0,4", "--metric=ncc",
                                                "--optimizer=wta", "--aggregation=guided",
                                                f"--aggregation-eps={v}", "-o", o / "s"], None),
    "stereo-confidence-floor": (numbers(small=(-2, 3), huge=10**9),
                                lambda w, v, o: ["stereo", w.left, w.right,
                                                 "--disparity-range=0,4", "--metric=ncc",
                                                 "--optimizer=wta", f"--confidence-floor={v}",
                                                 "-o", o / "s"], None),
    "stereo-scene-range": (lists_of(numbers(small=(-40, 40))),
                           lambda w, v, o: ["stereo", w.scene, f"--disparity-range={v}",
                                            "--optimizer=wta", "-o", o / "s"], None),
    "stereo-scene": (INPUT_TEXT,
                     lambda w, v, o: ["stereo", "--optimizer=wta", "-o", o / "s", "--",
                                      _input(w, v)], None),
    "stereo-left": (INPUT_TEXT,
                    lambda w, v, o: ["stereo", "--disparity-range=0,4", "-o", o / "s", "--",
                                     v, w.right], None),
    # --- depth (labels 2..8 or astronomically many)
    "depth-range": (lists_of(numbers(small=(-40, 40))),
                    lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                     f"--disparity-range={v}", "-o", o / "d"], None),
    "depth-labels": (SMALL_LABELS,
                     lambda w, v, o: ["depth", w.cap, f"--labels={v}", "--metric=ncc",
                                      "--optimizer=wta", "-o", o / "d"], None),
    "depth-metric": (names_or(["ncc", "rsncc", "census", "census-rsncc", "auto"]),
                     lambda w, v, o: ["depth", w.cap, "--labels=4", f"--metric={v}",
                                      "--optimizer=wta", "-o", o / "d"], None),
    "depth-optimizer": (names_or(["graphcut", "sgm", "wta"]),
                        lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                         f"--optimizer={v}", "-o", o / "d"], None),
    "depth-median-radius": (numbers(small=(-3, 64), huge=10**6),
                            lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                             "--optimizer=wta", f"--median-radius={v}",
                                             "-o", o / "d"], None),
    "depth-median-passes": (st.one_of(names_or(["auto"]), numbers(small=(-3, 30), huge=10**9)),
                            lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                             "--optimizer=wta", f"--median-passes={v}",
                                             "-o", o / "d"], None),
    "depth-texture-snr": (numbers(small=(-3, 64), huge=10**9),
                          lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                           "--optimizer=wta", f"--texture-snr={v}",
                                           "-o", o / "d"], None),
    "depth-aggregation-radius": (numbers(small=(-3, 70), huge=10**9),
                                 lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                                  "--optimizer=wta", "--aggregation=guided",
                                                  f"--aggregation-radius={v}", "-o", o / "d"],
                                 None),
    "depth-visibility-rounds": (numbers(small=(-2, 7), huge=10**9),
                                lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                                 "--optimizer=wta", f"--visibility-rounds={v}",
                                                 "-o", o / "d"], None),
    "depth-coarse-prior-levels": (numbers(small=(-2, 10), huge=10**9),
                                  lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                                   "--optimizer=wta",
                                                   f"--coarse-prior-levels={v}", "-o", o / "d"],
                                  None),
    "depth-missing-views": (names_or(["average", "neutral", "common"]),
                            lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                             "--optimizer=wta", f"--missing-views={v}",
                                             "-o", o / "d"], None),
    "depth-unseen-labels": (names_or(["share", "worst", "median"]),
                            lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                             "--optimizer=wta", f"--unseen-labels={v}",
                                             "-o", o / "d"], None),
    "depth-nearest-occluders": (names_or(["never", "before-last", "always"]),
                                lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                                 "--optimizer=wta", "--visibility-rounds=1",
                                                 f"--nearest-occluders={v}", "-o", o / "d"],
                                None),
    "depth-fusion-weights": (lists_of(numbers(small=(-2, 9))),
                             lambda w, v, o: ["depth", w.cap, "--labels=4",
                                              "--metric=census-rsncc", "--optimizer=wta",
                                              f"--fusion-weights={v}", "-o", o / "d"], None),
    "depth-downscale": (numbers(small=(-2, 5), huge=10**9),
                        lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                         "--optimizer=wta", f"--downscale={v}", "-o", o / "d"],
                        None),
    "depth-min-confidence": (numbers(small=(-2, 3), huge=10**9),
                             lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                              "--optimizer=wta", f"--min-confidence={v}",
                                              "-o", o / "d"], None),
    "depth-confidence-edge-px": (numbers(small=(-3, 1100), huge=10**9),
                                 lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                                  "--optimizer=wta", f"--confidence-edge-px={v}",
                                                  "-o", o / "d"], None),
    "depth-max-memory": (st.one_of(numbers(small=(-3, 10**6), huge=10**30),
                                   st.builds(lambda n, u: f"{n}{u}", numbers(small=(-2, 10**4)),
                                             st.sampled_from(["K", "M", "G", "T", "GB", "gib",
                                                              "MiB", "x", " G", "GG"]))),
                         lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                          "--optimizer=wta", f"--max-memory={v}", "-o", o / "d"],
                         None),
    "depth-defocus": (names_or(["off", "paper", "gaussian", "flat", "tv"]),
                      lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                       "--optimizer=wta", f"--defocus={v}", "-o", o / "d"],
                      None),
    "depth-method": (names_or(["hlf", "tao2013", "wang2015", "lin2015"]),
                     lambda w, v, o: ["depth", w.cap, "--labels=4", "--metric=ncc",
                                      f"--method={v}", "-o", o / "d"], None),
    "depth-input": (INPUT_TEXT,
                    lambda w, v, o: ["depth", "--labels=4", "--metric=ncc", "--optimizer=wta",
                                     "-o", o / "d", "--", _input(w, v)], None),
    # --- complete
    "complete-disparity": (INPUT_TEXT,
                           lambda w, v, o: ["complete", w.cap, "--stereo=none",
                                            f"--disparity={_input(w, v)}", "-o", o / "c"],
                           None),
    "complete-metric": (names_or(["ncc", "rsncc", "census", "ssd"]),
                        lambda w, v, o: ["complete", w.cap, "--use-ground-truth",
                                         f"--metric={v}", "--stereo=wta", "-o", o / "c"], None),
    "complete-stereo": (names_or(["none", "wta", "sgm", "graphcut"]),
                        lambda w, v, o: ["complete", w.cap, "--use-ground-truth",
                                         "--metric=ncc", f"--stereo={v}", "-o", o / "c"], None),
    "complete-downscale": (numbers(small=(-2, 5), huge=10**9),
                           lambda w, v, o: ["complete", w.cap, "--use-ground-truth",
                                            "--stereo=none", f"--downscale={v}", "-o", o / "c"],
                           None),
    # --- render
    "render-camera": (names_or(["CIE 1931", "cie 1931", "Nikon 5100", "Canon 1D Mark III"]),
                      lambda w, v, o: ["render", w.cap, f"--camera={v}", "-o", o / "r"], None),
    "render-white": (names_or(["D65", "A", "E", "D50"]),
                     lambda w, v, o: ["render", w.cube, f"--white={v}", "-o", o / "r"], None),
    "render-cube": (INPUT_TEXT,
                    lambda w, v, o: ["render", "-o", o / "r", "--", _input(w, v)], None),
    # --- refocus
    "refocus-disparity": (numbers(small=(-50, 50), huge=10**6),
                          lambda w, v, o: ["refocus", w.cap, f"--disparity={v}", "-o", o / "r"],
                          None),
    "refocus-sweep": (lists_of(numbers(small=(-5, 5), huge=10**10), max_size=4),
                      lambda w, v, o: ["refocus", w.cap, f"--sweep={v}", "-o", o / "r"], None),
    "refocus-profile": (st.one_of(
        names_or(["CIE 1931", "Nikon 5100", "bands"]),
        st.builds(lambda v: "band:" + v, numbers(small=(-1, 2000))),
        st.builds(lambda v: "weights:" + v, st.one_of(st.just("{w}"), HOSTILE_TEXT))),
        lambda w, v, o: ["refocus", w.cap, "--profile=" + v.replace("{w}", str(w.weights)),
                         "-o", o / "r"], None),
    "refocus-white": (names_or(["D65", "A", "E", "D50"]),
                      lambda w, v, o: ["refocus", w.cap, f"--white={v}", "-o", o / "r"], None),
    "refocus-fps": (numbers(small=(-2, 120), huge=10**4),
                    lambda w, v, o: ["refocus", w.cap, "--sweep=-1,1,2", f"--fps={v}",
                                     "-o", o / "r"], None),
    # --- spectrum
    "spectrum-at": (lists_of(numbers(small=(-5, 50))),
                    lambda w, v, o: ["spectrum", w.cube, f"--at={v}", "-o", o / "s.png"], None),
    "spectrum-view": (lists_of(numbers(small=(-2, 3), huge=10**9)),
                      lambda w, v, o: ["spectrum", w.cap, "--at=3,4", f"--view={v}",
                                       "-o", o / "s.png"], None),
    "spectrum-output": (PICTURE_NAMES,
                        lambda w, v, o: ["spectrum", w.cap, "--at=3,4", f"--output={o}/{v}"],
                        None),
    # --- calibrate (a 1 x 3 synthetic array's board shots) and ingest (its calibration)
    "calibrate-pattern": (st.one_of(st.sampled_from(["Cam-{index}.png", "Cam-{index:02d}.png",
                                                     "Cam-{row}{col}.png", "Cam-{col}.png"]),
                                    HOSTILE_TEXT),
                          lambda w, v, o: ["calibrate", w.shots, f"--pattern={v}", "--grid=1,3",
                                           "--board=6,4", "-o", o / "c"], None),
    "calibrate-grid": (lists_of(numbers(small=(-2, 4), huge=10**6)),
                       lambda w, v, o: ["calibrate", w.shots, "--pattern=Cam-{index}.png",
                                        f"--grid={v}", "--board=6,4", "-o", o / "c"], None),
    "calibrate-board": (lists_of(numbers(small=(-2, 12), huge=10**6)),
                        lambda w, v, o: ["calibrate", w.shots, "--pattern=Cam-{index}.png",
                                         "--grid=1,3", f"--board={v}", "-o", o / "c"], None),
    "calibrate-focal": (numbers(small=(-2, 400), huge=10**8),
                        lambda w, v, o: ["calibrate", w.shots, "--pattern=Cam-{index}.png",
                                         "--grid=1,3", "--board=6,4", f"--focal-px={v}",
                                         f"--square={v}", "-o", o / "c"], None),
    "ingest-calibration": (INPUT_TEXT,
                           lambda w, v, o: ["ingest", w.shots, "--pattern=Cam-{index}.png",
                                            f"--calibration={_input(w, v)}", "-o", o / "i"],
                           None),
    "ingest-wavelengths": (lists_of(numbers(small=(-5, 900)), max_size=5),
                           lambda w, v, o: ["ingest", w.shots, "--pattern=Cam-{index}.png",
                                            f"--calibration={w.cal}", f"--wavelengths={v}",
                                            "-o", o / "i"], None),
    "ingest-dead-saturation": (lists_of(numbers(small=(-2, 3), huge=10**9)),
                               lambda w, v, o: ["ingest", w.shots, "--pattern=Cam-{index}.png",
                                                f"--calibration={w.cal}", f"--dead={v}",
                                                f"--saturation={v.split(',')[0]}",
                                                "-o", o / "i"], None),
    "ingest-raw-bits": (numbers(small=(-2, 20), huge=10**9),
                        lambda w, v, o: ["ingest", w.shots, "--pattern=Cam-{index}.png",
                                         f"--calibration={w.cal}", f"--raw-bits={v}",
                                         "-o", o / "i"], None),
    "ingest-frames": (INPUT_TEXT,
                      lambda w, v, o: ["ingest", w.shots, "--pattern=Cam-{index}.png",
                                       f"--calibration={w.cal}", f"--dark={_input(w, v)}",
                                       f"--flat={_input(w, v)}", "-o", o / "i"], None),
    # --- batch: the option is parsed before the missing input is found (exit 4)
    "batch-workers": (numbers(small=(-2, 300), huge=10**12),
                      lambda w, v, o: ["batch", o / "no-such-capture", f"--workers={v}",
                                       "-o", o / "b"], None),
    "batch-downscale": (numbers(small=(-2, 70), huge=10**12),
                        lambda w, v, o: ["batch", o / "no-such-capture", f"--downscale={v}",
                                         "-o", o / "b"], None),
    "batch-min-confidence": (numbers(small=(-2, 3), huge=10**12),
                             lambda w, v, o: ["batch", o / "no-such-capture",
                                              f"--min-confidence={v}", "-o", o / "b"], None),
    "batch-confidence-floor": (numbers(small=(-2, 3), huge=10**12),
                               lambda w, v, o: ["batch", o / "no-such-capture",
                                                f"--confidence-floor={v}", "-o", o / "b"], None),
    # --- info
    "info-input": (INPUT_TEXT, lambda w, v, o: ["info", "--", _input(w, v)], None),
}

#: What an exit-0 run must have written, per command (``out`` is the -o path).
WRITTEN = {
    "synth": _lightfield_written,
    "demo": lambda out: _has(out, "report.html"),
    "stereo": lambda out: _has(out, "disparity.pfm", "disparity.png"),
    "depth": lambda out: _has(out, "disparity.pfm", "disparity.png"),
    "complete": lambda out: _has(out, "cube.h5", "reference_srgb.png"),
    "render": lambda out: _any_file(out, "rgb_*.png"),
    "refocus": lambda out: _any_file(out, "refocus*"),
    "spectrum": lambda out: out.is_file() and out.with_suffix(".csv").is_file(),
    "calibrate": lambda out: _has(out, "calibration.toml", "corners.png"),
    "ingest": lambda out: _has(out, "capture.toml", "valid_r0_c0.png"),
}


def _output_of(argv: list[str]) -> Path | None:
    for i, a in enumerate(argv):
        if a == "-o":
            return Path(argv[i + 1])
        if a.startswith("--output="):
            return Path(a[len("--output="):])
    return None


def _written_check(run: Run):
    """A callable proving the outputs of an exit-0 run exist."""
    command = run.argv[0]
    out = _output_of(run.argv)
    if command == "info":
        return lambda: run.out.strip() != ""
    if command == "convert":
        return lambda: (out.exists() or out.with_suffix(".hdr").is_file()) and (
            not out.is_dir() or any(out.iterdir()))
    return lambda: WRITTEN[command](out)


def fuzz_one(world: World, capfd, name: str, value: str) -> Run:
    _, build, _ = CASES[name]
    before = world.inputs()
    folder = world.fresh()
    with long_work_seen() as seen:
        run = run_main(build(world, value, folder), capfd)
    check(run, folder, _written_check(run))
    assert world.inputs() == before, f"the inputs changed: {run.argv!r}"
    assert run.code == 0 or not seen.started, \
        f"refused after long work started: {run.argv!r}\n{run.err.strip()}"
    return run


def run_fuzzer(name, world, capfd, profile) -> None:
    """Run the fuzzer of case ``name`` under a hypothesis settings ``profile``."""
    @profile
    @given(value=CASES[name][0])
    def fuzz(value):
        fuzz_one(world, capfd, name, value)
    fuzz()


@pytest.mark.parametrize("name", sorted(CASES))
def test_option_values(name, world, capfd):
    run_fuzzer(name, world, capfd, FUZZ)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CASES))
def test_option_values_heavy(name, world, capfd):
    run_fuzzer(name, world, capfd, FUZZ_HEAVY)


# ----------------------------------------------------------------------------- found bugs
#: Minimal reproducers of what the fuzzers found (each a traceback, a crash or exit 1 before
#: the fix); every one must now give a one-line error with a documented exit code.
FOUND_BY_FUZZING = {
    "long input name (exit 1, not 2)":
        lambda w, o: ["info", "--", "x" * 256],
    "long --disparity file name (exit 1)":
        lambda w, o: ["complete", w.cap, "--stereo=none", "--disparity=" + "x" * 256,
                      "-o", o / "c"],
    "~user in --camera (RuntimeError traceback)":
        lambda w, o: ["render", w.cap, "--camera=~nosuchuser/cam.csv", "-o", o / "r"],
    "NUL in -o (ValueError traceback)":
        lambda w, o: ["render", w.cap, "-o", str(o / "a") + "\x00b"],
    "NUL in spectrum -o (ValueError traceback)":
        lambda w, o: ["spectrum", w.cap, "--at=3,4", "-o", str(o / "a") + "\x00.png"],
    "newline in an input path (message on two lines)":
        lambda w, o: ["info", "--", "no\nsuch"],
    "spectrum -o x.h5 (matplotlib ValueError traceback)":
        lambda w, o: ["spectrum", w.cap, "--at=3,4", "-o", o / "x.h5"],
    "huge --median-radius (numba SystemError traceback)":
        lambda w, o: ["depth", w.cap, "--labels=4", "--metric=ncc", "--optimizer=wta",
                      "--median-radius=1000000000", "-o", o / "d"],
    "tao2013 with a 1e300 disparity range (OverflowError traceback)":
        lambda w, o: ["depth", w.cap, "--labels=4", "--method=tao2013",
                      "--disparity-range=-1e300,1e300", "-o", o / "d"],
    "--view=-- (argparse's own ValueError traceback, Python 3.11)":
        lambda w, o: ["convert", w.cube, "--view=--", "-o", o / "c.hdr"],
    "refocus --disparity=1e300 (file name too long, exit 1, empty folder left)":
        lambda w, o: ["refocus", w.cap, "--disparity=1e300", "-o", o / "r"],
    "a 236-byte -o name (its temporary name passed 255 bytes: exit 2 after the work)":
        lambda w, o: ["synth", "procedural", "--size=12,16", "--grid=2,2", "--no-pictures",
                      "--output=" + str(o / ("0" * 231 + ".hdf5"))],
}


@pytest.mark.parametrize("name", sorted(FOUND_BY_FUZZING))
def test_found_bug_stays_fixed(name, world, capfd):
    folder = world.fresh()
    run = run_main(FOUND_BY_FUZZING[name](world, folder), capfd)
    check(run, folder, _written_check(run))


#: Refused only after long work had started (found by running the fuzzers with the start of
#: long work as a sentinel, ``test_options_early``); each must now be refused before it.
REFUSED_LATE = {
    "refocus --profile bands (every band: no picture to write, refused after refocusing)":
        lambda w, o: ["refocus", w.cap, "--profile=bands", "-o", o / "r"],
    "depth --fusion-weights whose sum overflows (refused after the views were read)":
        lambda w, o: ["depth", w.cap, "--labels=4", "--fusion-weights=1e308,1e308",
                      "-o", o / "d"],
}


@pytest.mark.parametrize("name", sorted(REFUSED_LATE))
def test_refused_before_long_work(name, world, capfd):
    folder = world.fresh()
    with long_work_stopped():
        try:
            run = run_main(REFUSED_LATE[name](world, folder), capfd)
        except LongWork:
            pytest.fail(f"{name}: long work started before the refusal")
    assert run.code == 2
    check(run, folder)


def test_a_refusal_after_long_work_fails_the_fuzzers(world, capfd, monkeypatch):
    """The fuzzers' check of *when* a value is refused is live: a refusal planted in the
    last stage of ``depth``, after the views were matched and the labels solved, fails it."""
    from hyperlf import hlf
    from hyperlf.errors import InvalidInputError

    def refuse(*args, **kwargs):
        raise InvalidInputError("a planted refusal")

    monkeypatch.setattr(hlf, "edge_discount", refuse)
    with pytest.raises(AssertionError, match="refused after long work started"):
        fuzz_one(world, capfd, "depth-labels", "4")


def test_non_utf8_output_name_does_not_crash(world, tmp_path):
    """A file name that is not UTF-8 (here byte 0xff) reaches Python as a lone surrogate;
    OpenCV's imwrite given such a str crashed the whole process (SIGSEGV); images are now
    encoded in memory and written by Python."""
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = os.fsencode(tmp_path) + b"/\xff"
    proc = subprocess.run([sys.executable, "-m", "hyperlf", "-q", "synth", "procedural",
                           "--size=12,16", "--grid=2,2", "--no-pictures", "-o", out],
                          capture_output=True, timeout=120, env=env)
    assert proc.returncode == 0, (proc.returncode, proc.stderr[-800:])
    assert (tmp_path / os.fsdecode(b"\xff") / "capture.toml").is_file()
