"""Spectral tools: colour matching functions, cameras, illuminants, reflectances and filters.

Small functions over arrays, in the style of scikit-image. Every function is vectorised; the
spectral axis of a spectrum array is the last axis unless an ``axis`` argument says otherwise.
Wavelengths are in nanometres (nm) throughout.

colour-science is imported lazily, inside the functions that need it (it takes about a second
to import), so ``import hyperlf.spectral`` stays cheap. The only module state is a handful of
:func:`functools.lru_cache` lookup tables (CMF table, dominant-wavelength table, parsed data
files, resampled bases).

Data files
----------
The camspec camera database, the Munsell reflectances and the Thorlabs filter transmissions are
read from the benchmark data folder (environment variable ``HYPERLF_DATA``, see
:mod:`hyperlf.datasets`) or from an explicit path. They are never copied into the package.
colour-science's own tables (CMFs, illuminants, two cameras, the ColorChecker) are always
available, so everything here has a data-free fallback.

Conventions
-----------
* XYZ is scaled so that the reference white has ``Y = 1`` (not 100).
* "Linear sRGB" is IEC 61966-2-1 sRGB without its transfer function, D65 white = (1, 1, 1).
* Dominant wavelengths are on the CIE 1931 2-degree spectral locus unless an observer is given.
"""

from __future__ import annotations

import difflib
import math
import os
import re
from functools import lru_cache
from pathlib import Path
from typing import Sequence

import numpy as np

from . import _options as _opt
from .errors import DataNotFoundError, FormatError, InvalidInputError

__all__ = [
    "wavelengths_unknown",
    "CIE1931",
    "cmfs",
    "list_cameras",
    "camera_sensitivities",
    "load_camspec",
    "load_sensitivities_csv",
    "srgb_to_linear",
    "linear_to_srgb",
    "xyz_to_srgb_linear",
    "srgb_linear_to_xyz",
    "xyz_to_srgb",
    "xyz_to_xy",
    "spectrum_to_xyz",
    "spectrum_to_rgb",
    "illuminant_spd",
    "rgb_to_spectrum",
    "dominant_wavelength",
    "dominant_wavelength_for_filters",
    "load_munsell",
    "reflectance_library",
    "load_filter_transmissions",
    "filter_response",
    "FILTER_SHAPES",
    "MIN_FWHM",
    "MAX_FWHM",
    "MAX_WAVELENGTH",
    "sample_widths",
    "as_wavelengths",
    "illuminant_values",
]

#: Name of the default observer (colour-science's key).
CIE1931 = "CIE 1931 2 Degree Standard Observer"

#: Names that mean "the CIE 1931 colour matching functions" in :func:`camera_sensitivities`.
_XYZ_ALIASES = ("CIE 1931", "XYZ")

#: The D65 white point's xy chromaticity (IEC 61966-2-1).
_D65_XY = (0.3127, 0.3290)


def _xy_to_XYZ(xy) -> np.ndarray:
    """CIE xy chromaticities ``(..., 2)`` -> XYZ ``(..., 3)`` at luminance ``Y = 1``."""
    xy = np.asarray(xy, dtype=np.float64)
    x, y = xy[..., 0], xy[..., 1]
    return np.stack([x / y, np.ones_like(x), (1 - x - y) / y], axis=-1)


def _srgb_matrix() -> np.ndarray:
    """Linear sRGB -> XYZ: the primaries' XYZ scaled so that RGB (1, 1, 1) is the D65 white."""
    P = _xy_to_XYZ([[0.64, 0.33], [0.30, 0.60], [0.15, 0.06]]).T
    return P * np.linalg.solve(P, _xy_to_XYZ(_D65_XY))[None, :]


#: IEC 61966-2-1 sRGB primaries and D65 white -> XYZ (Y of white = 1). Derived from the
#: primaries x,y = (0.64, 0.33), (0.30, 0.60), (0.15, 0.06) and D65 (0.3127, 0.3290).
_M_RGB_TO_XYZ = _srgb_matrix()
_M_XYZ_TO_RGB = np.linalg.inv(_M_RGB_TO_XYZ)
_M_RGB_TO_XYZ.setflags(write=False)
_M_XYZ_TO_RGB.setflags(write=False)

#: Bradford cone-response matrix, for the optional chromatic adaptation in xyz_to_srgb_linear.
_BRADFORD = np.array([[0.8951, 0.2664, -0.1614],
                      [-0.7502, 1.7135, 0.0367],
                      [0.0389, -0.0685, 1.0296]])


# ---------------------------------------------------------------------------------------------
# small validation helpers
# ---------------------------------------------------------------------------------------------

def wavelengths_unknown(wavelengths) -> bool:
    """True for wavelengths that are all NaN: those of a cube completed from a capture whose
    filters were not given (its bands are then the cameras in raster order).

    Examples
    --------
    >>> wavelengths_unknown([np.nan, np.nan]), wavelengths_unknown([550.0, np.nan])
    (True, False)
    """
    if wavelengths is None:  # not given, which is not the same as given as unknown
        return False
    try:
        wl = np.asarray(wavelengths, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):  # not numbers: as_wavelengths says so
        return False
    return bool(wl.size) and bool(np.isnan(wl).all())


def as_wavelengths(wavelengths, name: str = "wavelengths") -> np.ndarray:
    """Validate wavelengths: a finite, non-empty 1-D float64 array (a scalar becomes 1-D).

    Parameters
    ----------
    wavelengths : array_like
        Wavelengths in nm.
    name : str
        What to call the argument in error messages.

    Returns
    -------
    ndarray
        ``(N,)`` float64.

    Raises
    ------
    InvalidInputError
        For non-numeric, empty, multi-dimensional or non-finite input; all NaN (a cube
        whose capture had no wavelengths) gets its own message.

    Examples
    --------
    >>> as_wavelengths(550)
    array([550.])
    """
    try:
        wl = _opt.real_array(wavelengths, name)  # too large for a float: inf, refused below
    except InvalidInputError:
        raise InvalidInputError(
            f"{name} must be a sequence of numbers in nm, got {type(wavelengths).__name__}"
        ) from None
    if wl.ndim == 0:
        wl = wl.reshape(1)
    if wl.ndim != 1 or wl.size == 0:
        raise InvalidInputError(
            f"{name} must be a non-empty 1-D array of wavelengths in nm, got shape {wl.shape}"
        )
    if wavelengths_unknown(wl):
        raise InvalidInputError(
            f"{name} are unknown (NaN), as in a cube completed from a capture without them: "
            "give them when the capture is made ('hyperlf ingest --wavelengths') and complete "
            "it again")
    if not np.all(np.isfinite(wl)):
        raise InvalidInputError(f"{name} contains NaN or infinite values; pass finite nm values")
    if not (wl.min() > 0 and wl.max() <= MAX_WAVELENGTH):
        raise InvalidInputError(f"{name} must be wavelengths in (0, {MAX_WAVELENGTH:g}] nm, got "
                                f"values in [{wl.min():g}, {wl.max():g}]")
    return wl


#: The longest wavelength (nm) any function takes: squares of wavelengths and of their
#: differences stay finite.
MAX_WAVELENGTH = 1e6


def _as_array(x, name: str, last: int | None = None) -> np.ndarray:
    try:
        arr = np.asarray(x)
    except Exception:  # pragma: no cover - exotic inputs
        raise InvalidInputError(f"{name} could not be converted to an array") from None
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise InvalidInputError(f"{name} must be a numeric array, got dtype {arr.dtype}")
    if np.iscomplexobj(arr):
        raise InvalidInputError(f"{name} must be real-valued, got dtype {arr.dtype}")
    if last is not None and (arr.ndim == 0 or arr.shape[-1] != last):
        raise InvalidInputError(
            f"{name} must have a last axis of length {last}, got shape {arr.shape}"
        )
    return arr


def _float(arr: np.ndarray) -> np.ndarray:
    """Float view of ``arr`` keeping float32 as float32 and promoting everything else to float64."""
    if arr.dtype in (np.float32, np.float64):
        return arr
    if arr.dtype == np.float16:
        return arr.astype(np.float32)
    return arr.astype(np.float64)


def sample_widths(wavelengths) -> np.ndarray:
    """Integration weight (nm) of each wavelength sample, for non-uniform sampling.

    Each sample represents the interval half-way to its neighbours (a Voronoi cell on the
    wavelength axis); the first and last samples are extended symmetrically, so that on a
    uniform grid every sample gets exactly the grid step (a plain Riemann sum, as CIE 015 and
    colour-science do). The order of ``wavelengths`` does not matter; a single sample gets
    width 1 nm.

    Parameters
    ----------
    wavelengths : array_like, shape (N,)
        Sample wavelengths in nm, any order.

    Returns
    -------
    ndarray, shape (N,)
        Widths in nm, in the order of ``wavelengths``.

    Examples
    --------
    On a uniform grid every sample weighs the grid step. Below, the 20 nm gap gives 430 nm a
    width of 20 nm and 410 nm (half-way to each neighbour) 15 nm, in the order given:

    >>> sample_widths([400.0, 410.0, 420.0]).tolist()
    [10.0, 10.0, 10.0]
    >>> sample_widths([430.0, 400.0, 410.0]).tolist()
    [20.0, 10.0, 15.0]
    """
    wl = as_wavelengths(wavelengths)
    if wl.size == 1:
        return np.ones(1)
    order = np.argsort(wl, kind="stable")
    s = wl[order]
    edges = np.empty(s.size + 1)
    edges[1:-1] = 0.5 * (s[1:] + s[:-1])
    edges[0] = s[0] - 0.5 * (s[1] - s[0])
    edges[-1] = s[-1] + 0.5 * (s[-1] - s[-2])
    widths = np.empty_like(wl)
    widths[order] = np.diff(edges)
    return widths


def _colour():
    """colour-science, imported lazily and without its side effect: on import it switches
    numpy's printing to the 1.13 style for the whole process (``np.set_printoptions``), which
    would change how a user's own arrays print."""
    import sys

    if "colour" not in sys.modules:
        options = np.get_printoptions()
        try:
            import colour  # noqa: F401
        finally:
            np.set_printoptions(**options)
    return sys.modules["colour"]


# ---------------------------------------------------------------------------------------------
# colour matching functions
# ---------------------------------------------------------------------------------------------

def _observer(observer) -> str:
    """``observer`` when it is text (a name; the tables are cached by it)."""
    if not isinstance(observer, str):
        raise InvalidInputError(f"observer must be a name such as {CIE1931!r}, got "
                                f"{_opt.shown(observer)}")
    return observer


@lru_cache(maxsize=8)
def _cmf_table(observer: str) -> tuple[np.ndarray, np.ndarray]:
    colour = _colour()
    try:
        msds = colour.MSDS_CMFS[observer]
    except KeyError:
        close = difflib.get_close_matches(observer, list(colour.MSDS_CMFS), n=3, cutoff=0.3)
        raise InvalidInputError(
            f"unknown observer {observer!r}; try one of {close or list(colour.MSDS_CMFS)[:4]}"
        ) from None
    wl = np.array(msds.wavelengths, dtype=np.float64)
    values = np.array(msds.values, dtype=np.float64)
    wl.setflags(write=False)
    values.setflags(write=False)
    return wl, values


def _interp_table(wavelengths: np.ndarray, table_wl: np.ndarray, table: np.ndarray,
                  outside: str = "zero") -> np.ndarray:
    """Linear interpolation of the columns of ``table`` (M, K) at ``wavelengths`` -> (N, K)."""
    out = np.empty((wavelengths.size, table.shape[1]))
    for k in range(table.shape[1]):  # K = 3 columns, not a per-pixel loop
        if outside == "zero":
            out[:, k] = np.interp(wavelengths, table_wl, table[:, k], left=0.0, right=0.0)
        else:  # hold the end values
            out[:, k] = np.interp(wavelengths, table_wl, table[:, k])
    return out


def cmfs(wavelengths, observer: str = CIE1931) -> np.ndarray:
    """Colour matching functions x̄, ȳ, z̄ sampled at the given wavelengths.

    Parameters
    ----------
    wavelengths : array_like, shape (N,)
        Wavelengths in nm, any order.
    observer : str
        A key of ``colour.MSDS_CMFS`` (default the CIE 1931 2-degree standard observer,
        tabulated 360-830 nm in 1 nm steps).

    Returns
    -------
    ndarray, shape (N, 3)
        x̄ȳz̄ linearly interpolated from the 1 nm table; zero outside the table.

    Examples
    --------
    ȳ is the photopic luminous efficiency V(λ), which peaks at 1 at 555 nm; past the end of
    the table (830 nm) all three functions are 0:

    >>> cmfs([555.0, 900.0])[:, 1].tolist()
    [1.0, 0.0]
    >>> cmfs(np.arange(400.0, 701.0, 10.0)).shape
    (31, 3)
    """
    wl = as_wavelengths(wavelengths)
    table_wl, table = _cmf_table(_observer(observer))
    return _interp_table(wl, table_wl, table, outside="zero")


# ---------------------------------------------------------------------------------------------
# cameras
# ---------------------------------------------------------------------------------------------

def _data_file(path, dataset: str, what: str, hint: str) -> Path:
    """``path`` if given, else the registered dataset; a missing file raises one clear error."""
    if path is None:
        from .datasets import dataset_path

        p = dataset_path(dataset)
    else:
        from .datasets import expand_user

        p = expand_user(path)
    if not p.is_file():
        raise DataNotFoundError(f"{what} {p} does not exist; pass {hint} or set HYPERLF_DATA")
    return p


@lru_cache(maxsize=8)
def _parse_camspec(path: str, mtime_ns: int) -> dict:
    """The cameras of the camspec text file ``path``: name -> (wavelengths, (33, 3))."""
    lines = _text_lines(path, "the camspec database")
    cameras: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    j = 0
    while j < len(lines):
        lineno, line = lines[j]
        if _numbers(line.split()) is not None:
            raise FormatError(
                f"{path}:{lineno}: numeric line without a camera name before it; the camspec "
                "format is a name line followed by 3 lines (R, G, B) of 33 values"
            )
        sens = _camspec_camera(path, lines[j:j + 4])
        if sens is None:  # header line (URL, description, separator)
            j += 1
            continue
        if line in cameras:
            raise FormatError(f"{path}:{lineno}: camera {line!r} appears twice")
        wl = np.arange(400.0, 721.0, 10.0)
        wl.setflags(write=False)
        sens.setflags(write=False)
        cameras[line] = (wl, sens)
        j += 4
    if not cameras:
        raise FormatError(f"{path} contains no camera; is it the camspec database text file?")
    return cameras


def _text_lines(path, expected: str) -> list[tuple[int, str]]:
    """The non-blank lines of the text file ``path`` with their numbers, stripped (a UTF-8
    byte-order mark dropped); ``expected`` names the content for the refusals."""
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise FormatError(f"{path} is not a UTF-8 text file; expected {expected}") from None
    except OSError as exc:
        raise FormatError(f"cannot read {path}: {exc.strerror or exc}") from None
    return [(i + 1, ln.strip()) for i, ln in enumerate(text.splitlines()) if ln.strip()]


def _numbers(tokens) -> list[float] | None:
    """The tokens as floats, or None where one is not a number."""
    try:
        return [float(t) for t in tokens]
    except ValueError:
        return None


def _camspec_camera(path: str, block: list[tuple[int, str]]) -> np.ndarray | None:
    """The ``(33, 3)`` sensitivities of the camera named on ``block``'s first line and given
    on the three lines after it, or None where no numeric line follows (a header line)."""
    (lineno, name), following = block[0], []
    for _, ln in block[1:]:
        values = _numbers(ln.split())
        if values is None:
            break
        following.append(values)
    if not following:
        return None
    if len(following) != 3:
        raise FormatError(f"{path}:{lineno}: camera {name!r} has {len(following)} data "
                          "line(s), expected 3 (R, G, B)")
    for (ln_no, _), values in zip(block[1:], following):
        if len(values) != 33:
            raise FormatError(
                f"{path}:{ln_no}: camera {name!r} has {len(values)} values on a line, expected "
                "33 (400-720 nm in 10 nm steps)"
            )
    sens = np.array(following, dtype=np.float64).T  # (33, 3)
    if not np.all(np.isfinite(sens)):
        raise FormatError(f"{path}:{lineno}: camera {name!r} has non-finite values")
    return sens


def load_camspec(path: str | os.PathLike | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Read the camspec database of 28 camera spectral sensitivities.

    Source: J. Jiang, D. Liu, J. Gu, S. Süsstrunk, "What is the space of spectral sensitivity
    functions for digital color cameras?", IEEE Workshop on Applications of Computer Vision
    (WACV) 2013, http://www.gujinwei.org/research/camspec/. Please cite it when you use these
    curves.

    The file is *not* shipped with hyperlf (benchmark data is never copied into the package or
    the repository); it is read from ``$HYPERLF_DATA/spectral/camspec/camspec_database.txt`` or
    from an explicit ``path``. The parse is cached per path (and modification time).

    Format: free header lines, then for every camera a name line followed by three lines of 33
    values (R, G, B at 400, 410, ..., 720 nm).

    Parameters
    ----------
    path : path-like, optional
        The database file; default ``hyperlf.datasets.dataset_path("camspec")``.

    Returns
    -------
    dict
        Camera name -> ``(wavelengths (33,), sensitivities (33, 3))``, in file order. The arrays
        are read-only (shared by the cache); copy them before modifying.

    Raises
    ------
    DataNotFoundError
        No path given and ``HYPERLF_DATA`` unset, or the file does not exist.
    FormatError
        The file does not follow the format above.

    Examples
    --------
    A stand-in file with one camera in the camspec layout (an R line of 1s, a G line of 2s and
    a B line of 3s), so that this runs without the data; the lines become columns, 400-720 nm:

    >>> import pathlib, tempfile
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "camspec.txt"
    >>> _ = f.write_text("My camera\\n" + "".join(" ".join([v] * 33) + "\\n" for v in "123"))
    >>> wl, sens = load_camspec(f)["My camera"]
    >>> wl[[0, 1, -1]].tolist(), sens.shape, sens[0].tolist()
    ([400.0, 410.0, 720.0], (33, 3), [1.0, 2.0, 3.0])
    """
    p = _data_file(path, "camspec", "camspec database", "the path of camspec_database.txt")
    return dict(_parse_camspec(str(p.resolve()), p.stat().st_mtime_ns))


def _csv_tokens(line: str) -> list[str]:
    """The line's values: comma-separated (one trailing comma tolerated), else by
    whitespace."""
    if "," not in line:
        return line.split()
    tokens = [t.strip() for t in line.split(",")]
    return tokens[:-1] if tokens[-1] == "" else tokens


def _sensitivity_row(p: Path, lineno: int, line: str) -> list[float]:
    """One row ``wavelength_nm, r, g, b`` of a sensitivity file, checked."""
    values = _numbers(_csv_tokens(line))  # a non-blank line has at least one token
    if values is None:
        raise FormatError(
            f"{p}:{lineno}: non-numeric value in {line[:60]!r}; expected 4 numbers "
            "wavelength_nm, r, g, b"
        )
    if len(values) != 4:
        raise FormatError(
            f"{p}:{lineno}: {len(values)} column(s), expected 4 (wavelength_nm, r, g, b)"
        )
    if not all(math.isfinite(v) for v in values):
        raise FormatError(f"{p}:{lineno}: NaN or infinite value; all values must be finite")
    return values


def load_sensitivities_csv(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read camera sensitivities from a CSV/text file.

    Format: one row per wavelength with four columns ``wavelength_nm, r, g, b``, separated by
    commas or whitespace. An optional header row (first non-blank line, not numeric), blank
    lines and lines starting with ``#`` are ignored. Wavelengths must be finite, distinct and in
    increasing order; values must be finite. At least two rows.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    wavelengths : ndarray, shape (N,)
        nm.
    sensitivities : ndarray, shape (N, 3)
        R, G, B as tabulated (not normalised).

    Raises
    ------
    DataNotFoundError
        The file does not exist.
    FormatError
        Any malformed content, with the line number.

    Examples
    --------
    A two-row file with a header line, read back as written:

    >>> import pathlib, tempfile
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "camera.csv"
    >>> _ = f.write_text("wavelength_nm,r,g,b\\n500,0.1,0.8,0.2\\n600,0.9,0.3,0.0\\n")
    >>> wl, sens = load_sensitivities_csv(f)
    >>> wl.tolist(), sens.tolist()
    ([500.0, 600.0], [[0.1, 0.8, 0.2], [0.9, 0.3, 0.0]])
    """
    from .datasets import expand_user

    p = expand_user(path)
    if not p.is_file():
        raise DataNotFoundError(f"sensitivity file {p} does not exist; check the path")
    lines = [(n, ln) for n, ln in _text_lines(p, "CSV rows wavelength_nm,r,g,b")
             if not ln.startswith("#")]
    rows = [_sensitivity_row(p, n, ln) for k, (n, ln) in enumerate(lines)
            if k or _numbers(_csv_tokens(ln)) is not None]  # the first may be a header
    if len(rows) < 2:
        raise FormatError(
            f"{p} has {len(rows)} data row(s); expected at least 2 rows of wavelength_nm, r, g, b"
        )
    arr = np.array(rows, dtype=np.float64)
    wl = arr[:, 0]
    if np.any(np.diff(wl) <= 0):
        raise FormatError(f"{p}: wavelengths must be strictly increasing (sort the rows, drop duplicates)")
    return wl, arr[:, 1:4]


def _colour_camera_names() -> list[str]:
    colour = _colour()

    return [k for k in colour.MSDS_CAMERA_SENSITIVITIES]


def _camspec_names_if_available() -> list[str]:
    from .datasets import has_data

    if not has_data("camspec"):
        return []
    try:
        return list(load_camspec())
    except (FormatError, DataNotFoundError):
        return []


def list_cameras() -> list[str]:
    """Names accepted by :func:`camera_sensitivities`.

    Returns
    -------
    list of str
        ``"CIE 1931"`` and ``"XYZ"`` (the CIE 1931 CMFs), colour-science's
        ``colour.MSDS_CAMERA_SENSITIVITIES`` cameras, and the 28 camspec cameras (Jiang et al.
        2013) when ``HYPERLF_DATA`` points to the data.

    Examples
    --------
    >>> names = list_cameras()
    >>> names[:2], "Sigma SDMerill (NPL)" in names
    (['CIE 1931', 'XYZ'], True)
    """
    return list(_XYZ_ALIASES) + _colour_camera_names() + _camspec_names_if_available()


def _norm_name(s: str) -> str:
    return re.sub(r"[^0-9a-z]+", "", s.casefold())


def _match_camera(name: str, names: Sequence[str]) -> str:
    """Resolve a camera name: exact (case-insensitive), then punctuation-insensitive, then
    unique prefix, then unique substring."""
    folded = {n.casefold(): n for n in names}
    if name.casefold() in folded:
        return folded[name.casefold()]
    key = _norm_name(name)
    if not key:
        raise InvalidInputError(f"camera name {name!r} is empty; use one of list_cameras()")
    normed = {}
    for n in names:
        normed.setdefault(_norm_name(n), n)
    if key in normed:
        return normed[key]
    for test in (lambda k: k.startswith(key), lambda k: key in k):
        hits = sorted({normed[k] for k in normed if test(k)})
        if len(hits) == 1:
            return hits[0]
        if len(hits) > 1:
            raise InvalidInputError(
                f"camera name {name!r} is ambiguous: it matches {', '.join(hits[:6])}"
                f"{' ...' if len(hits) > 6 else ''}; give more of the name"
            )
    close = difflib.get_close_matches(name, list(names), n=4, cutoff=0.3)
    if not close:
        close = difflib.get_close_matches(name.casefold(), list(folded), n=4, cutoff=0.3)
        close = [folded[c] for c in close]
    hint = f"did you mean {', '.join(repr(c) for c in close)}?" if close else \
        "hyperlf.spectral.list_cameras() lists them"
    raise InvalidInputError(
        f"unknown camera {name!r}; {hint} (or pass a CSV file wavelength_nm,r,g,b; "
        "camspec cameras need HYPERLF_DATA)"
    )


def _looks_like_path(name_or_path) -> bool:
    if isinstance(name_or_path, os.PathLike):
        return True
    if not isinstance(name_or_path, str):
        return False  # a name or a path is text; camera_sensitivities says what is wrong
    s = name_or_path
    return (s.lower().endswith((".csv", ".txt", ".tsv", ".dat")) or os.sep in s
            or (os.altsep is not None and os.altsep in s) or s.startswith("~")
            or Path(s).is_file())


def camera_sensitivities(name_or_path, wavelengths) -> np.ndarray:
    """RGB spectral sensitivities of a camera, resampled at the given wavelengths.

    Parameters
    ----------
    name_or_path : str or path-like
        ``"CIE 1931"`` / ``"XYZ"`` (the CIE 1931 2-degree CMFs x̄ȳz̄), a camera name from
        :func:`list_cameras` (case- and punctuation-insensitive; a unique prefix or substring,
        e.g. ``"sdmerill"``, or ``"nikon d5100"`` among camspec's cameras, which need
        ``HYPERLF_DATA``, is enough), or the path of a CSV file with
        columns ``wavelength_nm, r, g, b`` (see :func:`load_sensitivities_csv`).
    wavelengths : array_like, shape (N,)
        nm.

    Returns
    -------
    ndarray, shape (N, 3)
        Sensitivities as tabulated (not normalised), linearly interpolated; zero outside the
        measured range.

    Raises
    ------
    InvalidInputError
        Unknown or ambiguous name (the message lists close names).
    DataNotFoundError, FormatError
        A CSV path that does not exist or is malformed.

    Examples
    --------
    "CIE 1931" gives the CMFs themselves (ȳ is 1 at 555 nm); a part of a name is enough:

    >>> S = camera_sensitivities("CIE 1931", [450.0, 555.0, 650.0])
    >>> S.shape, bool(np.allclose(S, cmfs([450.0, 555.0, 650.0]))), float(S[1, 1])
    ((3, 3), True, 1.0)
    >>> camera_sensitivities("sdmerill", np.arange(400.0, 701.0, 10.0)).shape
    (31, 3)
    """
    wl = as_wavelengths(wavelengths)
    if _looks_like_path(name_or_path):
        table_wl, table = load_sensitivities_csv(name_or_path)
        return _interp_table(wl, table_wl, table, outside="zero")
    if not isinstance(name_or_path, str):
        raise InvalidInputError(
            f"camera must be a name or a path, got {type(name_or_path).__name__}"
        )
    colour_names = _colour_camera_names()
    camspec = {}
    from .datasets import has_data

    if has_data("camspec"):
        try:
            camspec = load_camspec()
        except FormatError:
            camspec = {}
    names = list(_XYZ_ALIASES) + colour_names + list(camspec)
    match = _match_camera(name_or_path, names)
    if match in _XYZ_ALIASES:
        return cmfs(wl)
    if match in camspec:
        table_wl, table = camspec[match]
        return _interp_table(wl, table_wl, table, outside="zero")
    colour = _colour()

    msds = colour.MSDS_CAMERA_SENSITIVITIES[match]
    return _interp_table(wl, np.asarray(msds.wavelengths, float), np.asarray(msds.values, float),
                         outside="zero")


# ---------------------------------------------------------------------------------------------
# sRGB, XYZ
# ---------------------------------------------------------------------------------------------

def srgb_to_linear(x) -> np.ndarray:
    """Decode the sRGB transfer function (IEC 61966-2-1), elementwise.

    ``x / 12.92`` for ``x <= 0.04045``, else ``((x + 0.055) / 1.055) ** 2.4``. Negative values
    are mapped antisymmetrically (``f(-x) = -f(x)``), as in extended sRGB, so nothing becomes
    NaN. Values are not clipped. float32 stays float32; other types become float64.

    Parameters
    ----------
    x : array_like
        sRGB-encoded values, floats (1 = white; integers are refused).

    Returns
    -------
    ndarray
        Linear values, same shape.

    Examples
    --------
    >>> srgb_to_linear(np.array([0.0, 1.0])).tolist()
    [0.0, 1.0]
    """
    a = _as_array(x, "x")
    if np.issubdtype(a.dtype, np.integer):   # 8-bit values would come out 0..524946
        raise InvalidInputError(f"sRGB values must be floats in [0, 1], got {a.dtype} "
                                "integers; divide by 255 (or 65535) first")
    a = _float(a)
    if not np.isfinite(a).all():
        raise InvalidInputError("sRGB values must be finite")
    ax = np.abs(a)
    try:
        with np.errstate(over="raise"):
            out = np.where(ax <= 0.04045, ax / 12.92, ((ax + 0.055) / 1.055) ** 2.4)
    except FloatingPointError:
        raise InvalidInputError(f"sRGB values must be of a size whose linear value the "
                                f"{a.dtype} type holds (they are 0..1), got up to "
                                f"{float(ax.max()):g}") from None
    return (np.sign(a) * out).astype(a.dtype, copy=False)


def linear_to_srgb(x) -> np.ndarray:
    """Encode with the sRGB transfer function (IEC 61966-2-1), elementwise.

    ``12.92 x`` for ``x <= 0.0031308``, else ``1.055 x ** (1/2.4) - 0.055``; antisymmetric for
    negative values; not clipped. Inverse of :func:`srgb_to_linear`.

    Parameters
    ----------
    x : array_like
        Linear values.

    Returns
    -------
    ndarray
        sRGB-encoded values, same shape.

    Examples
    --------
    >>> x = np.array([0.001, 0.2, 0.9])
    >>> bool(np.allclose(srgb_to_linear(linear_to_srgb(x)), x))
    True
    """
    a = _float(_as_array(x, "x"))
    ax = np.abs(a)
    out = np.where(ax <= 0.0031308, 12.92 * ax, 1.055 * ax ** (1 / 2.4) - 0.055)
    return (np.sign(a) * out).astype(a.dtype, copy=False)


def _adaptation_to_d65(white) -> np.ndarray:
    """Bradford adaptation from the xy ``white`` to D65.  It refuses ``y <= 0`` and a cone
    response 0 (a gain would be infinite).  A negative response is kept: the white of a few
    bands far apart (410 and 700 nm) has one, and its colours are a rough guess anyway."""
    xy = _white_tuple(white)
    ls = _BRADFORD @ _xy_to_XYZ(xy) if xy[1] > 0 else np.zeros(3)
    if not np.all(ls != 0):
        raise InvalidInputError(
            f"white must be the xy chromaticity of a light (y > 0), like (1/3, 1/3) or "
            f"(0.3127, 0.3290), got {xy}")
    ld = _BRADFORD @ _xy_to_XYZ(_D65_XY)
    return np.linalg.inv(_BRADFORD) @ np.diag(ld / ls) @ _BRADFORD


def xyz_to_srgb_linear(xyz, white=None) -> np.ndarray:
    """CIE XYZ -> linear sRGB (IEC 61966-2-1 matrix, D65 white).

    White point handling: by default ``xyz`` is taken as relative to D65, i.e. XYZ of D65
    (x, y = 0.3127, 0.3290, Y = 1) maps to RGB (1, 1, 1); no chromatic adaptation. Pass
    ``white`` (the xy chromaticity of the white of ``xyz``, e.g. ``(1/3, 1/3)`` for the
    equal-energy normalisation of :func:`spectrum_to_xyz` without illuminant) to apply a Bradford
    adaptation from that white to D65 first, so that white maps to (1, 1, 1) times its Y.

    Parameters
    ----------
    xyz : array_like, shape (..., 3)
        Y of the white = 1.
    white : (float, float), optional

    Returns
    -------
    ndarray, shape (..., 3)
        Unclipped linear sRGB (out-of-gamut colours have components outside [0, 1]).

    Examples
    --------
    The XYZ of D65 (x, y = 0.3127, 0.3290 at Y = 1) is sRGB's white; with ``white`` the
    equal-energy white, XYZ = (1, 1, 1), is adapted onto it:

    >>> x, y = 0.3127, 0.3290
    >>> np.round(xyz_to_srgb_linear([x / y, 1.0, (1 - x - y) / y]), 4).tolist()
    [1.0, 1.0, 1.0]
    >>> np.round(xyz_to_srgb_linear([1.0, 1.0, 1.0], white=(1 / 3, 1 / 3)), 4).tolist()
    [1.0, 1.0, 1.0]
    """
    a = _float(_as_array(xyz, "xyz", last=3))
    M = _M_XYZ_TO_RGB
    if white is not None:
        M = M @ _adaptation_to_d65(white)
    return (a @ M.T.astype(a.dtype)).astype(a.dtype, copy=False)


def srgb_linear_to_xyz(rgb) -> np.ndarray:
    """Linear sRGB -> CIE XYZ (D65 white, Y of white = 1). Inverse of :func:`xyz_to_srgb_linear`.

    Parameters
    ----------
    rgb : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3)

    Examples
    --------
    White goes to D65's XYZ and pure red to the red primary, whose Y is the well-known
    luminance weight 0.2126; the two conversions undo each other:

    >>> np.round(srgb_linear_to_xyz([[1.0, 1.0, 1.0], [1.0, 0.0, 0.0]]), 4).tolist()
    [[0.9505, 1.0, 1.0891], [0.4124, 0.2126, 0.0193]]
    >>> rgb = np.array([0.2, 0.5, 0.9])
    >>> bool(np.allclose(xyz_to_srgb_linear(srgb_linear_to_xyz(rgb)), rgb))
    True
    """
    a = _float(_as_array(rgb, "rgb", last=3))
    return (a @ _M_RGB_TO_XYZ.T.astype(a.dtype)).astype(a.dtype, copy=False)


def xyz_to_srgb(xyz, white=None, *, clip: bool = False) -> np.ndarray:
    """CIE XYZ -> encoded sRGB: :func:`xyz_to_srgb_linear` then :func:`linear_to_srgb`.

    See :func:`xyz_to_srgb_linear` for ``white``. With ``clip=True`` the linear values are
    clipped to [0, 1] before encoding (a simple gamut clip); otherwise nothing is clipped.

    Returns
    -------
    ndarray, shape (..., 3)

    Examples
    --------
    An 18 % grey under D65 encodes to ``1.055 * 0.18 ** (1 / 2.4) - 0.055``; a light twice as
    bright as white clips to 1:

    >>> white = srgb_linear_to_xyz([1.0, 1.0, 1.0])
    >>> np.round(xyz_to_srgb(0.18 * white), 4).tolist()
    [0.4614, 0.4614, 0.4614]
    >>> np.round(xyz_to_srgb(2 * white, clip=True), 4).tolist()
    [1.0, 1.0, 1.0]
    """
    lin = xyz_to_srgb_linear(xyz, white=white)
    if _opt.flag(clip, "clip"):
        lin = np.clip(lin, 0.0, 1.0)
    return linear_to_srgb(lin)


def xyz_to_xy(xyz, fallback=(1 / 3, 1 / 3)) -> np.ndarray:
    """CIE XYZ -> xy chromaticity, safe for black.

    Parameters
    ----------
    xyz : array_like, shape (..., 3)
    fallback : (float, float)
        Chromaticity returned where ``X + Y + Z`` is zero (or not finite); default the
        equal-energy white E, so black reads as achromatic.

    Returns
    -------
    ndarray, shape (..., 2)

    Examples
    --------
    D65's XYZ gives its chromaticity (0.3127, 0.3290); black gives the fallback, E:

    >>> np.round(xyz_to_xy([[0.95047, 1.0, 1.08883], [0.0, 0.0, 0.0]]), 4).tolist()
    [[0.3127, 0.329], [0.3333, 0.3333]]
    """
    a = _float(_as_array(xyz, "xyz", last=3))
    fallback = _opt.real_array(fallback, "fallback")  # NaN may mark black as unknown
    if fallback.shape != (2,):
        raise InvalidInputError(f"fallback must be an xy pair like (1/3, 1/3), got "
                                f"{_opt.shown(fallback)}")
    s = a.sum(axis=-1, keepdims=True)
    ok = np.isfinite(s) & (np.abs(s) > np.finfo(a.dtype).tiny)
    safe = np.where(ok, s, 1)
    xy = a[..., :2] / safe
    return np.where(ok, xy, np.asarray(fallback, dtype=a.dtype)).astype(a.dtype, copy=False)


# ---------------------------------------------------------------------------------------------
# illuminants, spectra -> colour
# ---------------------------------------------------------------------------------------------

def illuminant_spd(name: str, wavelengths) -> np.ndarray:
    """Relative spectral power of a CIE illuminant, resampled and normalised to mean 1.

    Parameters
    ----------
    name : str
        A key of ``colour.SDS_ILLUMINANTS`` (case-insensitive), e.g. ``"D65"``, ``"E"``, ``"A"``,
        ``"D50"``, ``"FL2"``.
    wavelengths : array_like, shape (N,)
        nm.

    Returns
    -------
    ndarray, shape (N,)
        Linear interpolation of the tabulated SPD; the end values are held outside the table
        (colour-science's constant extrapolation). Scaled to mean 1 over ``wavelengths``.

    Examples
    --------
    E is flat. CIE A (a 2856 K Planckian radiator) is tabulated as 100 at 560 nm and 14.708 at
    400 nm, a ratio the normalisation keeps:

    >>> illuminant_spd("E", [400.0, 500.0, 600.0]).tolist()
    [1.0, 1.0, 1.0]
    >>> s = illuminant_spd("A", [400.0, 560.0, 700.0])
    >>> round(float(s[0] / s[1]), 4), round(float(s.mean()), 4)
    (0.1471, 1.0)
    """
    wl = as_wavelengths(wavelengths)
    table_wl, table = _illuminant_table(str(name))
    spd = np.interp(wl, table_wl, table)
    m = spd.mean()
    if not m > 0:
        raise InvalidInputError(f"illuminant {name!r} has no power over the given wavelengths")
    return spd / m


@lru_cache(maxsize=32)
def _illuminant_table(name: str) -> tuple[np.ndarray, np.ndarray]:
    colour = _colour()

    keys = list(colour.SDS_ILLUMINANTS)
    folded = {k.casefold(): k for k in keys}
    key = folded.get(name.casefold())
    if key is None:
        close = difflib.get_close_matches(name.upper(), keys, n=4, cutoff=0.3)
        raise InvalidInputError(
            f"unknown illuminant {name!r}; try one of {close or ['D65', 'E', 'A', 'D50']}"
        )
    sd = colour.SDS_ILLUMINANTS[key]
    wl = np.array(sd.wavelengths, dtype=np.float64)
    v = np.array(sd.values, dtype=np.float64)
    wl.setflags(write=False)
    v.setflags(write=False)
    return wl, v


def illuminant_values(illuminant, wl: np.ndarray) -> np.ndarray | None:
    """An illuminant's SPD on ``wl``: a name (:func:`illuminant_spd`), an array or None.

    Parameters
    ----------
    illuminant : str, array_like or None
        A colour-science illuminant name (e.g. ``"D65"``), one value per wavelength, or None.
    wl : ndarray
        ``(N,)`` wavelengths in nm.

    Returns
    -------
    ndarray or None
        ``(N,)`` float64 SPD, or None when ``illuminant`` is None.

    Raises
    ------
    InvalidInputError
        For an array of the wrong shape or with non-finite values.

    Examples
    --------
    >>> illuminant_values([1.0, 2.0], np.array([500.0, 600.0]))
    array([1., 2.])
    """
    if illuminant is None:
        return None
    if isinstance(illuminant, str):
        return illuminant_spd(illuminant, wl)
    ill = _float(_as_array(illuminant, "illuminant")).astype(np.float64)
    if ill.shape != wl.shape:
        raise InvalidInputError(
            f"illuminant must be a name or an array of shape {wl.shape} (one value per "
            f"wavelength), got shape {ill.shape}"
        )
    if not np.all(np.isfinite(ill)):
        raise InvalidInputError("illuminant contains NaN or infinite values")
    return check_magnitude(ill, "illuminant")


#: Largest value of a spectrum a user gives (an illuminant, a white, a camera's
#: sensitivities): far beyond any light, and a product of two of them stays finite.
MAX_SPECTRAL_VALUE = 1e100


def check_magnitude(values: np.ndarray, label: str) -> np.ndarray:
    """``values`` (finite) when none is larger than :data:`MAX_SPECTRAL_VALUE` in size
    (:func:`hyperlf._options.array`'s bound)."""
    return _opt.array(values, label, bound=MAX_SPECTRAL_VALUE)


def _spectral_axis(arr: np.ndarray, n: int, axis: int, name: str) -> np.ndarray:
    if arr.ndim == 0:
        raise InvalidInputError(f"{name} must have a spectral axis of length {n}, got a scalar")
    axis = _opt.integer(axis, "axis", -arr.ndim, maximum=arr.ndim - 1)
    try:
        moved = np.moveaxis(arr, axis, -1)
    except (ValueError, IndexError):
        raise InvalidInputError(f"axis {axis} is out of range for {name} of shape {arr.shape}") from None
    if moved.shape[-1] != n:
        raise InvalidInputError(
            f"{name} has {moved.shape[-1]} samples along axis {axis} but {n} wavelengths were "
            "given; pass one wavelength per band"
        )
    return moved


def _spectra_last(spectra, n: int, axis: int) -> np.ndarray:
    """``spectra`` as a float array with its spectral axis (``n`` samples at ``axis``) last."""
    return _spectral_axis(_float(_as_array(spectra, "spectra")), n, axis, "spectra")


def _weigh_spectra(moved: np.ndarray, weights: np.ndarray, axis: int) -> np.ndarray:
    """``moved`` (spectral axis last) times ``weights`` (N, k), in the spectra's dtype; the
    k-axis takes the spectral axis' place ``axis`` (checked by :func:`_spectral_axis`)."""
    axis = int(axis)
    out = moved @ weights.astype(moved.dtype)
    return np.moveaxis(out, -1, axis) if axis not in (-1, moved.ndim - 1) else out


def spectrum_to_xyz(spectra, wavelengths, *, illuminant=None, normalise: str | None = "equal-energy",
                    observer: str = CIE1931, axis: int = -1) -> np.ndarray:
    """CIE XYZ of spectra (reflectances, or emission spectra when ``illuminant`` is None).

    ``XYZ = k * sum_b w_b S(λ_b) I(λ_b) cmf(λ_b)``, a Riemann sum with per-sample widths
    ``w_b`` from :func:`sample_widths` (the interval half-way to the neighbouring samples), so any
    non-uniform, unsorted wavelength sampling works. ``I`` is 1 without illuminant.

    Parameters
    ----------
    spectra : array_like, shape (..., N)
        Spectral axis ``axis`` (default last).
    wavelengths : array_like, shape (N,)
        nm.
    illuminant : str or array_like (N,), optional
        A name for :func:`illuminant_spd` or the SPD sampled at ``wavelengths``.
    normalise : {"equal-energy", "white", None}
        ``"equal-energy"`` (alias ``"white"``): ``k`` makes the reference white (a flat
        spectrum of 1, times the illuminant when given — i.e. the perfect reflector) have
        ``Y = 1``. ``None``/``"none"``: ``k = 1`` (raw weighted sum, units of spectrum x nm).
    observer : str
        Key of ``colour.MSDS_CMFS``.
    axis : int
        Spectral axis of ``spectra``; the XYZ axis replaces it.

    Returns
    -------
    ndarray, shape (..., 3)
        XYZ; float32 for float32 input, else float64.

    Raises
    ------
    InvalidInputError
        Shape mismatch, or the wavelengths lie outside the CMFs (no luminance).

    Examples
    --------
    A flat spectrum, the equal-energy white E, has Y = 1 and chromaticity (1/3, 1/3); lit by
    D65, the perfect reflector takes D65's chromaticity (0.3127, 0.3290):

    >>> wl = np.arange(380.0, 781.0, 5.0)
    >>> xyz = spectrum_to_xyz(np.ones(wl.size), wl)
    >>> round(float(xyz[1]), 4), np.round(xyz_to_xy(xyz), 4).tolist()
    (1.0, [0.3333, 0.3333])
    >>> d65 = spectrum_to_xyz(np.ones(wl.size), wl, illuminant="D65")
    >>> np.round(xyz_to_xy(d65), 4).tolist()
    [0.3127, 0.329]
    """
    _opt.choice(normalise, "normalise", ("equal-energy", "white", None, "none"))
    wl = as_wavelengths(wavelengths)
    moved = _spectra_last(spectra, wl.size, axis)
    weights = cmfs(wl, observer) * sample_widths(wl)[:, None]  # (N, 3)
    ill = illuminant_values(illuminant, wl)
    if ill is not None:
        weights = weights * ill[:, None]
    if normalise in ("equal-energy", "white"):
        y_white = weights[:, 1].sum()
        if not y_white > 0:
            raise InvalidInputError(
                f"the wavelengths {wl.min():g}-{wl.max():g} nm carry no luminance (CMFs cover "
                "360-830 nm); cannot normalise to Y = 1"
            )
        weights = weights / y_white
    elif normalise not in (None, "none"):
        raise InvalidInputError(
            f"normalise must be 'equal-energy', 'white' or None, got {normalise!r}"
        )
    return _weigh_spectra(moved, weights, axis)


def spectrum_to_rgb(spectra, wavelengths, *, camera="CIE 1931", white_balance: bool = True,
                    illuminant=None, axis: int = -1) -> np.ndarray:
    """Camera RGB of spectra: colour sensor emulation (SPEC §8, §5.3).

    ``RGB_k = sum_b spectrum_b S_k(λ_b)`` (a plain sum over bands, no widths: each band is one
    filtered image), optionally times an illuminant. With ``white_balance`` each channel is
    divided by ``sum_b I(λ_b) S_k(λ_b)``, so a flat spectrum of 1 (under the illuminant) gives
    RGB = (1, 1, 1); this is exactly SPEC §5.3's ``V_k = sum_v P S_k / sum_v S_k``.

    Parameters
    ----------
    spectra : array_like, shape (..., N)
        Spectral axis ``axis`` (default last), e.g. a cube ``[R, C, B, H, W]`` with ``axis=2``.
    wavelengths : array_like, shape (N,)
        Band centres, nm, any order.
    camera : str, path-like or array_like (N, 3)
        Anything :func:`camera_sensitivities` accepts, or sensitivities already sampled at
        ``wavelengths``.
    white_balance : bool
    illuminant : str or array_like (N,), optional
        Multiplies the spectra (and the white used for white balance).
    axis : int
        Spectral axis; the RGB axis replaces it.

    Returns
    -------
    ndarray, shape (..., 3)
        Camera RGB, of the dtype :func:`spectrum_to_xyz` gives.

    Raises
    ------
    InvalidInputError
        Shape mismatch, or a channel with zero response over the bands while white-balancing.

    Examples
    --------
    White-balanced, a flat spectrum reads (1, 1, 1) whatever the camera; the RGB axis takes
    the place of the spectral axis:

    >>> wl = np.arange(400.0, 701.0, 10.0)
    >>> np.round(spectrum_to_rgb(np.ones(wl.size), wl, camera="sdmerill"), 4).tolist()
    [1.0, 1.0, 1.0]
    >>> spectrum_to_rgb(np.ones((2, wl.size, 4, 5)), wl, axis=1).shape
    (2, 3, 4, 5)
    """
    _opt.flag(white_balance, "white_balance")
    wl = as_wavelengths(wavelengths)
    moved = _spectra_last(spectra, wl.size, axis)
    if isinstance(camera, (str, os.PathLike)):
        S = camera_sensitivities(camera, wl)
    else:
        S = _float(_as_array(camera, "camera", last=3)).astype(np.float64)
        if S.shape != (wl.size, 3):
            raise InvalidInputError(
                f"camera sensitivities must have shape ({wl.size}, 3) to match the wavelengths, "
                f"got {S.shape}"
            )
    ill = illuminant_values(illuminant, wl)
    if ill is not None:
        S = S * ill[:, None]
    if white_balance:
        white = S.sum(axis=0)
        if np.any(white <= 0):
            dead = [c for c, v in zip("RGB", white) if v <= 0]
            raise InvalidInputError(
                f"camera channel(s) {', '.join(dead)} have no response at {wl.min():g}-"
                f"{wl.max():g} nm; cannot white-balance (use white_balance=False or other bands)"
            )
        S = S / white
    return _weigh_spectra(moved, S, axis)


# ---------------------------------------------------------------------------------------------
# RGB -> spectrum (Mallett & Yuksel 2019)
# ---------------------------------------------------------------------------------------------

@lru_cache(maxsize=32)
def _mallett_basis(wl_key: tuple) -> np.ndarray:
    colour = _colour()

    msds = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    table_wl = np.asarray(msds.wavelengths, dtype=np.float64)
    table = np.asarray(msds.values, dtype=np.float64)
    basis = _interp_table(np.asarray(wl_key, dtype=np.float64), table_wl, table, outside="hold")
    basis = basis.T.copy()  # (3, N)
    basis.setflags(write=False)
    return basis


def rgb_to_spectrum(rgb_linear, wavelengths) -> np.ndarray:
    """Linear sRGB -> smooth reflectance spectra with the Mallett & Yuksel (2019) basis.

    ``spectrum(λ) = r B_r(λ) + g B_g(λ) + b B_b(λ)`` with colour-science's
    ``colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019`` (tabulated 380-780 nm / 5 nm,
    linearly interpolated; the end values are held outside that range). The basis sums to 1 at
    every wavelength, so RGB (1, 1, 1) gives a flat spectrum of 1, and for RGB in [0, 1] the
    spectrum is in [0, 1] (a physical reflectance). Under illuminant D65 the spectrum's XYZ
    reproduces the RGB (see :func:`spectrum_to_xyz` with ``illuminant="D65"``).

    Reference: I. Mallett, C. Yuksel, "Spectral Primary Decomposition for Rendering with sRGB
    Reflectance", Eurographics Symposium on Rendering 2019.

    Parameters
    ----------
    rgb_linear : array_like, shape (..., 3)
        Linear (not gamma-encoded) sRGB; use :func:`srgb_to_linear` first on 8-bit images.
    wavelengths : array_like, shape (N,)
        nm.

    Returns
    -------
    ndarray, shape (..., N)
        float32 for float32 input, else float64.

    Examples
    --------
    Grey (1, 1, 1) becomes the flat spectrum 1, and under D65 the XYZ of a spectrum gives its
    RGB back:

    >>> wl = np.arange(380.0, 781.0, 5.0)
    >>> bool(np.allclose(rgb_to_spectrum([1.0, 1.0, 1.0], wl), 1.0, atol=1e-4))
    True
    >>> s = rgb_to_spectrum([0.8, 0.4, 0.1], wl)
    >>> np.round(xyz_to_srgb_linear(spectrum_to_xyz(s, wl, illuminant="D65")), 3).tolist()
    [0.8, 0.4, 0.1]
    """
    wl = as_wavelengths(wavelengths)
    a = _float(_as_array(rgb_linear, "rgb_linear", last=3))
    basis = _mallett_basis(tuple(wl.tolist()))
    return a @ basis.astype(a.dtype)


# ---------------------------------------------------------------------------------------------
# dominant wavelength
# ---------------------------------------------------------------------------------------------

_DW_LUT_SIZE = 1 << 18
#: The largest table ``lut_size`` may ask for (128 MiB); far finer than the locus' 0.1 nm.
_DW_LUT_MAX = 1 << 24


@lru_cache(maxsize=16)
def _dominant_lut(white: tuple, lut_size: int, observer: str, step: float = 0.1):
    """Hue angle -> wavelength table for one white point.

    The spectral locus is the polyline through the tabulated (1 nm) CMF chromaticities, as in
    colour-science. ``phi`` is the clockwise hue angle around ``white`` measured from the first
    (shortest) wavelength; it grows with wavelength. In the tails the CIE 1931 locus is nearly
    stationary (beyond ~700 nm every sample has xy = (0.73469, 0.26531) to 1e-7, wiggling by
    rounding noise), so a table sample is kept only if it advances the hue by more than
    ``min_step`` rad over the last kept one: the table is monotone and each ill-defined tail
    hue maps to the shortest wavelength reaching it. The kept polyline is then resampled every
    ``step`` nm (linear in xy) and tabulated on ``lut_size`` uniform hue angles.
    """
    min_step = 1e-6
    table_wl, table = _cmf_table(observer)
    s = table.sum(axis=1)
    ok = s > 0
    table_wl, xy_t = table_wl[ok], table[ok, :2] / s[ok, None]
    wx, wy = white
    theta_t = np.unwrap(np.arctan2(xy_t[:, 1] - wy, xy_t[:, 0] - wx))
    phi_t = theta_t[0] - theta_t  # increasing with wavelength (the locus runs clockwise)
    if phi_t[-1] <= 0 or phi_t[-1] >= 2 * np.pi or not np.all(np.isfinite(phi_t)):
        raise InvalidInputError(
            f"white point {white} is not inside the spectral locus; pass an xy chromaticity "
            "such as (1/3, 1/3) (E) or (0.3127, 0.3290) (D65)"
        )
    keep_t = np.zeros(phi_t.size, dtype=bool)
    last = -np.inf
    for i, p in enumerate(phi_t):  # ~471 table samples, once per white point
        if p > last + min_step:
            keep_t[i] = True
            last = p
    table_wl, xy_t = table_wl[keep_t], xy_t[keep_t]
    fine = np.arange(table_wl[0], table_wl[-1] + step / 2, step)
    x = np.interp(fine, table_wl, xy_t[:, 0])
    y = np.interp(fine, table_wl, xy_t[:, 1])
    theta = np.unwrap(np.arctan2(y - wy, x - wx))
    phi = theta[0] - theta
    keep = np.empty(phi.size, dtype=bool)
    keep[0] = True
    keep[1:] = phi[1:] > np.maximum.accumulate(phi)[:-1]
    phi_k, wl_k = phi[keep], fine[keep]
    span = float(phi_k[-1])
    grid = np.linspace(0.0, span, lut_size)
    lut = np.interp(grid, phi_k, wl_k)  # 2 MB
    lut.setflags(write=False)
    return float(theta[0]), span, lut, (float(wl_k[0]), float(wl_k[-1]))


def _white_tuple(white) -> tuple:
    return _opt.real_pair(np.ravel(_opt.real_array(white, "white")), "white",
                          "an xy pair like (1/3, 1/3)")


def _hue_phi(xy: np.ndarray, white: tuple, theta0: float) -> tuple[np.ndarray, np.ndarray]:
    dx = xy[..., 0] - white[0]
    dy = xy[..., 1] - white[1]
    phi = np.mod(theta0 - np.arctan2(dy, dx), 2 * np.pi)
    return phi, np.hypot(dx, dy)


def _lut_lookup(phi: np.ndarray, span: float, lut: np.ndarray) -> np.ndarray:
    n = lut.size
    with np.errstate(divide="ignore", invalid="ignore"):  # a span of 0: nan_to_num decides
        f = np.clip(np.nan_to_num(phi / span), 0.0, 1.0) * (n - 1)
    i = np.minimum(f.astype(np.intp), n - 2)
    t = f - i
    return lut[i] * (1 - t) + lut[i + 1] * t


def _check_xy(xy) -> np.ndarray:
    return _as_array(xy, "xy", last=2).astype(np.float64, copy=False)


def dominant_wavelength(xy, white=(1 / 3, 1 / 3), *, lut_size: int = _DW_LUT_SIZE,
                        observer: str = CIE1931) -> tuple[np.ndarray, np.ndarray]:
    """Dominant wavelength of chromaticities on the spectral locus, via a cached lookup table.

    The hue angle of ``xy`` around ``white`` is looked up (linear interpolation) in a table of
    ``lut_size`` uniformly spaced angles -> wavelength, built once per (white, observer) from
    the locus sampled every 0.1 nm (cached). The locus is the polyline through the 1 nm CMF
    chromaticities, as in colour-science.

    Convention (same as ``colour.dominant_wavelength``): a *purple* colour, whose hue falls in
    the gap closed by the line of purples, has no dominant wavelength; its **complementary**
    wavelength (the locus point opposite, through the white) is returned **with a negative
    sign**, and ``purple`` is True. colour-science returns the wavelength of the 1 nm table
    sample nearest to the intersection, so it is quantised to 1 nm; this function returns the
    interpolated (continuous) value: the two agree within 0.5 nm where the locus is well
    conditioned. In the CIE 1931 tails the locus is nearly a point and the wavelength is
    ill-defined (colour-science then returns an arbitrary sample of the cluster, e.g. any of
    700-830 nm); here the shortest wavelength reaching that hue is returned (so never more than
    ~700 nm for CIE 1931), and the locus point itself agrees with colour-science's.

    Parameters
    ----------
    xy : array_like, shape (..., 2)
        CIE xy chromaticities (e.g. from :func:`xyz_to_xy`).
    white : (float, float)
        Achromatic point; default E (1/3, 1/3) as in SPEC §5.3. D65 is (0.3127, 0.3290).
    lut_size : int
        Number of hue-angle entries (default 262144, angular step ~1.7e-5 rad, i.e. <= 0.2 nm
        even at 697 nm where the CIE 1931 locus almost stalls).
    observer : str
        Key of ``colour.MSDS_CMFS``.

    Returns
    -------
    wavelength : ndarray, shape (...)
        nm; negative complementary wavelength for purples; NaN where ``xy`` equals the white
        point or is not finite.
    purple : ndarray of bool, shape (...)

    Examples
    --------
    A monochromatic light is its own dominant wavelength; a mix of 450 nm and 650 nm light is
    a purple, returned as minus its complementary wavelength:

    >>> wl, purple = dominant_wavelength(xyz_to_xy(cmfs([550.0, 600.0])))
    >>> np.round(wl, 2).tolist(), purple.tolist()
    ([550.0, 600.0], [False, False])
    >>> wl, purple = dominant_wavelength(xyz_to_xy(cmfs([450.0, 650.0]).sum(axis=0)))
    >>> bool(wl < 0), bool(purple)
    (True, True)
    """
    a = _check_xy(xy)
    w = _white_tuple(white)
    lut_size = _opt.integer(lut_size, "lut_size", 16, maximum=_DW_LUT_MAX)
    theta0, span, lut, _ = _dominant_lut(w, lut_size, _observer(observer))
    phi, r = _hue_phi(a, w, theta0)
    purple = phi > span
    phi_c = np.where(purple, np.mod(phi + np.pi, 2 * np.pi), phi)
    wl = _lut_lookup(phi_c, span, lut)
    wl = np.where(purple, -wl, wl)
    bad = ~np.isfinite(r) | (r == 0)
    wl = np.where(bad, np.nan, wl)
    purple = purple & ~bad
    return wl, purple


def dominant_wavelength_for_filters(xy, lambda_min: float, lambda_max: float,
                                    *, white=(1 / 3, 1 / 3), achromatic_radius: float = 0.01,
                                    lut_size: int = _DW_LUT_SIZE,
                                    observer: str = CIE1931) -> np.ndarray:
    """Dominant wavelength mapped into a filter range (SPEC §5.3 rule).

    * near-achromatic (xy within ``achromatic_radius`` of ``white``, Euclidean in xy, or xy
      not finite) -> the middle of the range, ``(lambda_min + lambda_max) / 2``;
    * purple (no dominant wavelength) -> the nearer end of the filter range, *nearer in hue
      angle*: the hue of the colour is compared (around ``white``, going through the purple
      gap) with the hues of the locus points at ``lambda_min`` and ``lambda_max``; the smaller
      angular distance wins (reddish purples -> ``lambda_max``, bluish purples -> ``lambda_min``);
    * otherwise the dominant wavelength clipped to ``[lambda_min, lambda_max]``.

    Parameters
    ----------
    xy : array_like, shape (..., 2)
    lambda_min, lambda_max : float
        Filter range in nm, ``lambda_min <= lambda_max``.
    white : (float, float)
    achromatic_radius : float
        xy distance (>= 0).

    Returns
    -------
    ndarray, shape (...)
        nm, always within ``[lambda_min, lambda_max]``.

    Examples
    --------
    With filters from 520 to 700 nm, 550 nm light keeps its wavelength, 500 nm light is
    clipped to 520 nm and the white E takes the middle of the range:

    >>> xy = xyz_to_xy(cmfs([550.0, 500.0]))
    >>> np.round(dominant_wavelength_for_filters(xy, 520, 700), 2).tolist()
    [550.0, 520.0]
    >>> float(dominant_wavelength_for_filters([1 / 3, 1 / 3], 520, 700))
    610.0
    """
    lo, hi = _opt.real(lambda_min, "lambda_min"), _opt.real(lambda_max, "lambda_max")
    if not lo <= hi:
        raise InvalidInputError(
            f"filter range must satisfy lambda_min <= lambda_max (finite nm), got {lo}, {hi}"
        )
    achromatic_radius = _opt.number(achromatic_radius, "achromatic_radius")
    lut_size = _opt.integer(lut_size, "lut_size", 16, maximum=_DW_LUT_MAX)
    observer = _observer(observer)
    a = _check_xy(xy)
    w = _white_tuple(white)
    theta0, span, lut, _ = _dominant_lut(w, lut_size, observer)
    wl, purple = dominant_wavelength(a, w, lut_size=lut_size, observer=observer)
    phi, r = _hue_phi(a, w, theta0)
    # hue angles of the range ends on the locus (phi grows with wavelength)
    ends = np.array([lo, hi])
    table_wl, table = _cmf_table(observer)
    s = table.sum(axis=1)
    okk = s > 0
    ex = np.interp(ends, table_wl[okk], table[okk, 0] / s[okk])
    ey = np.interp(ends, table_wl[okk], table[okk, 1] / s[okk])
    phi_ends = np.mod(theta0 - np.arctan2(ey - w[1], ex - w[0]), 2 * np.pi)
    # a purple hue lies beyond phi_ends[1] (red side) and before phi_ends[0] + 2 pi (blue side)
    d_hi = phi - phi_ends[1]
    d_lo = phi_ends[0] + 2 * np.pi - phi
    purple_pick = np.where(d_hi <= d_lo, hi, lo)
    out = np.where(purple, purple_pick, np.clip(np.abs(wl), lo, hi))
    achromatic = ~np.isfinite(r) | (r <= achromatic_radius) | ~np.isfinite(wl)
    return np.where(achromatic, 0.5 * (lo + hi), out)


# ---------------------------------------------------------------------------------------------
# reflectances
# ---------------------------------------------------------------------------------------------

@lru_cache(maxsize=4)
def _parse_munsell(path: str, mtime_ns: int):
    import scipy.io

    try:
        mat = scipy.io.loadmat(path)
    except Exception as exc:  # scipy raises several types for corrupt files
        raise FormatError(f"cannot read {path} as a MATLAB file: {exc}") from None
    if "munsell" not in mat:
        raise FormatError(f"{path} has no variable 'munsell'; expected the UEF Munsell matt file")
    m = np.asarray(mat["munsell"], dtype=np.float64)
    if m.ndim != 2 or m.shape[0] != 421 or m.shape[1] < 1269:
        raise FormatError(
            f"{path}: variable 'munsell' has shape {m.shape}, expected (421, >=1269) "
            "(380-800 nm x chips)"
        )
    refl = np.ascontiguousarray(m[:, :1269].T)
    wl = np.arange(380.0, 801.0, 1.0)
    wl.setflags(write=False)
    refl.setflags(write=False)
    return wl, refl


def load_munsell(path: str | os.PathLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Reflectance spectra of the 1269 matt Munsell chips, 380-800 nm in 1 nm steps.

    Source: University of Eastern Finland spectral database; J. P. S. Parkkinen, J. Hallikainen,
    T. Jaaskelainen, "Characteristic spectra of Munsell colors", J. Opt. Soc. Am. A 6(2),
    318-322 (1989). Cite it when you use these spectra.

    Read from ``$HYPERLF_DATA/spectral/munsell_uef_matt/munsell380_800_final.mat`` (variable
    ``munsell``, 421 x 1273) or an explicit path; only the first 1269 columns are the original
    measurements (SPEC §10), the rest are dropped. Cached per path.

    Returns
    -------
    wavelengths : ndarray, shape (421,)
    reflectances : ndarray, shape (1269, 421)
        In [0, 1]; read-only (cached), copy before modifying.

    Examples
    --------
    A stand-in file of the same layout (a flat grey), so that this runs without the data:
    380-800 nm in 1 nm steps is 421 samples, and the 4 columns after the 1269th are dropped:

    >>> import os, tempfile, scipy.io
    >>> f = os.path.join(tempfile.mkdtemp(), "munsell.mat")
    >>> scipy.io.savemat(f, {"munsell": np.full((421, 1273), 0.5)})
    >>> wl, refl = load_munsell(f)
    >>> wl[[0, -1]].tolist(), refl.shape
    ([380.0, 800.0], (1269, 421))
    """
    p = _data_file(path, "munsell", "Munsell file", "the .mat path")
    return _parse_munsell(str(p.resolve()), p.stat().st_mtime_ns)


@lru_cache(maxsize=1)
def _colorchecker() -> tuple[np.ndarray, np.ndarray]:
    colour = _colour()

    sds = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    first = next(iter(sds.values()))
    wl = np.asarray(first.wavelengths, dtype=np.float64)
    refl = np.stack([np.interp(wl, np.asarray(sd.wavelengths, float), np.asarray(sd.values, float))
                     for sd in sds.values()])  # 24 patches
    wl.setflags(write=False)
    refl.setflags(write=False)
    return wl, refl


def reflectance_library(source: str = "auto", wavelengths=None) -> tuple[np.ndarray, np.ndarray]:
    """A library of real reflectance spectra.

    Parameters
    ----------
    source : {"auto", "munsell", "colorchecker"}
        ``"munsell"``: the 1269 Munsell chips (:func:`load_munsell`, needs ``HYPERLF_DATA``).
        ``"colorchecker"``: the 24 ColorChecker patches (Ohta's measurements, colour-science's
        ``SDS_COLOURCHECKERS["ColorChecker N Ohta"]``, 380-780 nm / 5 nm), always available.
        ``"auto"``: Munsell when the data is available, else the ColorChecker.
    wavelengths : array_like (N,), optional
        Resample to these wavelengths (linear; end values held outside the table).

    Returns
    -------
    wavelengths : ndarray, shape (N,)
    reflectances : ndarray, shape (n, N)

    Examples
    --------
    The ColorChecker, 380-780 nm in 5 nm steps. Its six neutral patches (18-23) have nominal
    optical densities D of 0.05 to 1.5; under D65 their luminance factors are 10**-D, to 0.01:

    >>> wl, refl = reflectance_library("colorchecker")
    >>> refl.shape, wl[[0, -1]].tolist()
    ((24, 81), [380.0, 780.0])
    >>> Y = spectrum_to_xyz(refl[18:], wl, illuminant="D65")[:, 1]
    >>> bool(np.allclose(Y, 10 ** -np.array([0.05, 0.23, 0.44, 0.70, 1.05, 1.5]), atol=0.01))
    True
    """
    from .datasets import has_data

    src = str(source).lower()
    if src == "auto":
        src = "munsell" if has_data("munsell") else "colorchecker"
    if src == "munsell":
        wl, refl = load_munsell()
    elif src in ("colorchecker", "colourchecker"):
        wl, refl = _colorchecker()
    else:
        raise InvalidInputError(
            f"unknown reflectance source {source!r}; use 'auto', 'munsell' or 'colorchecker'"
        )
    if wavelengths is None:
        return wl, refl
    new = as_wavelengths(wavelengths)
    out = _interp_table(new, wl, refl.T, outside="hold").T
    return new, np.ascontiguousarray(out)


# ---------------------------------------------------------------------------------------------
# filters
# ---------------------------------------------------------------------------------------------

@lru_cache(maxsize=4)
def _parse_filters(path: str, mtime_ns: int):
    lines = [ln for _, ln in _text_lines(path, "a filter transmission table (CSV)")]
    if len(lines) < 3:
        raise FormatError(f"{path} has too few lines for a filter transmission table")
    header = [h.strip() for h in lines[0].split(",")]
    centres = []
    for h in header[1:]:
        m = re.search(r"(\d+(?:\.\d+)?)", h)
        if not m:
            raise FormatError(
                f"{path}: column {h!r} has no centre wavelength in its name (e.g. FBH430-10)"
            )
        centres.append(float(m.group(1)))
    rows = []
    for k, ln in enumerate(lines[1:], start=2):
        vals = _numbers(t.strip() for t in ln.split(","))
        if vals is None or len(vals) != len(header):
            raise FormatError(
                f"{path}: line {k} does not have {len(header)} numeric columns"
            )
        rows.append(vals)
    arr = np.array(rows, dtype=np.float64)
    if not np.all(np.isfinite(arr)) or np.any(np.diff(arr[:, 0]) <= 0):
        raise FormatError(f"{path}: non-finite values or wavelengths not increasing")
    wl = arr[:, 0]
    trans = arr[:, 1:].T
    if trans.max() > 1.5:  # stored in percent
        trans = trans / 100.0
    trans = np.clip(trans, 0.0, 1.0)
    c = np.array(centres)
    for a in (wl, trans, c):
        a.setflags(write=False)
    return wl, trans, c


def load_filter_transmissions(path: str | os.PathLike | None = None):
    """Measured band-pass filter transmissions (Thorlabs FBH 10 nm FWHM series).

    The CSV has a header ``wavelength_nm, FBH430-10, FBH440-10, ...`` and one row per nm
    (380-800 nm), transmissions in percent. Read from ``$HYPERLF_DATA`` (dataset
    ``"thorlabs"``) or an explicit path; cached.

    Returns
    -------
    wavelengths : ndarray, shape (N,)
        nm.
    transmissions : ndarray, shape (F, N)
        Fraction in [0, 1] (percent values are divided by 100).
    centres : ndarray, shape (F,)
        Nominal centre wavelengths from the column names, nm (the shipped file has filters at
        430-460 and 660-780 nm only).

    Examples
    --------
    A stand-in table with one filter, in percent, so that this runs without the data: the
    values become fractions and the centre is read from the column name:

    >>> import pathlib, tempfile
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "filters.csv"
    >>> _ = f.write_text("wavelength_nm,FBH550-10\\n540,0\\n550,80\\n560,0\\n")
    >>> wl, trans, centres = load_filter_transmissions(f)
    >>> wl.tolist(), trans.tolist(), centres.tolist()
    ([540.0, 550.0, 560.0], [[0.0, 0.8, 0.0]], [550.0])
    """
    p = _data_file(path, "thorlabs", "filter file", "the CSV path")
    return _parse_filters(str(p.resolve()), p.stat().st_mtime_ns)


def filter_response(center_nm, wavelengths, shape: str = "dirac", *, fwhm: float = 10.0,
                    path: str | os.PathLike | None = None, align: str = "centroid") -> np.ndarray:
    """Normalised weights with which a band-pass filter samples a spectrum (SPEC §6).

    ``band_value = sum_b weight_b * spectrum(λ_b)``; weights are non-negative and sum to 1 for
    each centre. For ``gaussian`` and ``thorlabs`` the weight is ``T(λ_b) * w_b`` with the
    sample widths ``w_b`` of :func:`sample_widths`, so non-uniform grids integrate correctly.

    Parameters
    ----------
    center_nm : float or array_like, shape (M,)
        Filter centre wavelengths, nm.
    wavelengths : array_like, shape (N,)
        Wavelengths at which the spectrum is known, nm.
    shape : {"dirac", "gaussian", "thorlabs"}
        ``dirac`` (paper §3): the spectrum sampled at the centre, i.e. linear-interpolation
        (hat) weights on the two neighbouring samples (one-hot when the centre is a sample);
        the centre must lie within the wavelengths. ``gaussian``: a Gaussian of full width at
        half maximum ``fwhm``. ``thorlabs``: the measured transmission of the Thorlabs filter
        whose nominal centre is nearest, shifted so that it is centred on ``center_nm``
        (``align="centroid"``: its transmission-weighted centroid over the pass band, T > 1 % of
        the peak; ``align="nominal"``: its nominal centre, keeping the real filter's offset).
    fwhm : float
        nm, for ``gaussian``.
    path : path-like, optional
        Filter CSV for ``thorlabs`` (default the dataset).

    Returns
    -------
    ndarray, shape (N,) for a scalar centre, (M, N) otherwise.

    Raises
    ------
    InvalidInputError
        Unknown shape, bad fwhm, a Dirac centre outside the wavelengths, or a filter that does
        not overlap the wavelengths.

    Examples
    --------
    A Gaussian's weights sum to 1 and, half its FWHM from the centre, are half its peak; a
    Dirac half-way between two samples weighs each by 1/2:

    >>> wl = np.arange(500.0, 601.0, 1.0)
    >>> w = filter_response(550, wl, "gaussian", fwhm=10)
    >>> round(float(w.sum()), 6), round(float(w[55] / w[50]), 4)
    (1.0, 0.5)
    >>> filter_response(555, [550.0, 560.0]).tolist()
    [0.5, 0.5]
    """
    wl = as_wavelengths(wavelengths)
    c_arr = _opt.real_array(center_nm, "center_nm")
    scalar = c_arr.ndim == 0
    c = as_wavelengths(c_arr.reshape(-1), "center_nm")
    shape = _opt.choice(shape.lower() if isinstance(shape, str) else shape, "shape",
                        tuple(FILTER_SHAPES))
    W = FILTER_SHAPES[shape](c, wl, fwhm=fwhm, path=path, align=align)
    tot = W.sum(axis=1, keepdims=True)
    if np.any(~(tot > 0)):
        bad = c[~(tot[:, 0] > 0)]
        raise InvalidInputError(
            f"filter(s) at {bad[:4].tolist()} nm do not overlap the wavelengths "
            f"{wl.min():g}-{wl.max():g} nm"
        )
    W = W / tot
    return W[0] if scalar else W


def _dirac_weights(c: np.ndarray, wl: np.ndarray, **_) -> np.ndarray:
    """The spectrum sampled at each centre: linear-interpolation (hat) weights on the two
    neighbouring samples; the centres must lie within the wavelengths."""
    order = np.argsort(wl, kind="stable")
    s = wl[order]
    if np.any(c < s[0] - 1e-9) or np.any(c > s[-1] + 1e-9):
        raise InvalidInputError(
            f"dirac filter centre(s) outside the wavelengths {s[0]:g}-{s[-1]:g} nm; "
            "add samples there or use shape='gaussian'"
        )
    W = np.zeros((c.size, wl.size))
    if s.size == 1:
        W[:, 0] = 1.0
        return W
    j = np.clip(np.searchsorted(s, c, side="right") - 1, 0, s.size - 2)
    gap = s[j + 1] - s[j]
    t = np.where(gap > 0, (c - s[j]) / np.where(gap > 0, gap, 1), 0.0)
    t = np.clip(t, 0.0, 1.0)
    rows = np.arange(c.size)
    W[rows, order[j]] += 1 - t
    W[rows, order[j + 1]] += t
    return W


def _gaussian_weights(c: np.ndarray, wl: np.ndarray, *, fwhm, **_) -> np.ndarray:
    """A Gaussian of full width at half maximum ``fwhm`` nm (:data:`MIN_FWHM` to
    :data:`MAX_FWHM`) on each centre, times the sample widths."""
    fwhm = _opt.number(fwhm, "fwhm", at_least=MIN_FWHM, at_most=MAX_FWHM)
    sigma = fwhm / (2 * np.sqrt(2 * np.log(2)))
    return np.exp(-0.5 * ((wl[None, :] - c[:, None]) / sigma) ** 2) * sample_widths(wl)[None, :]


def _thorlabs_weights(c: np.ndarray, wl: np.ndarray, *, path, align, **_) -> np.ndarray:
    """The measured transmission of the Thorlabs filter whose nominal centre is nearest,
    moved onto each centre (by its centroid or its nominal centre), times the sample
    widths; zero outside the measured range."""
    _opt.choice(align, "align", ("centroid", "nominal"))
    f_wl, trans, centres = load_filter_transmissions(path)
    k = np.argmin(np.abs(centres[None, :] - c[:, None]), axis=1)
    if align == "centroid":
        band = trans >= 0.01 * trans.max(axis=1, keepdims=True)
        tb = np.where(band, trans, 0.0)
        ref = (tb * f_wl).sum(1) / tb.sum(1)
    else:
        ref = centres
    q = wl[None, :] - (c - ref[k])[:, None]  # T(lambda - shift) sampled on wl
    W = np.empty((c.size, wl.size))
    for m in range(c.size):  # one row per filter, vectorised over wavelengths
        W[m] = np.interp(q[m], f_wl, trans[k[m]], left=0.0, right=0.0)
    return W * sample_widths(wl)[None, :]


#: Band-pass filter shapes by name (SPEC §6): each gives the raw weights ``(M, N)`` of ``M``
#: centres on ``N`` wavelengths, which :func:`filter_response` normalises.
FILTER_SHAPES = {"dirac": _dirac_weights, "gaussian": _gaussian_weights,
                 "thorlabs": _thorlabs_weights}

#: Full width at half maximum of a Gaussian filter, nm: at least MIN_FWHM (the Gaussian's
#: exponent stays finite over any wavelengths) and at most MAX_FWHM (wider than any spectrum).
MIN_FWHM, MAX_FWHM = 1e-3, 1000.0

