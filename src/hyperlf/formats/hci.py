"""HCI 4D light field benchmark scenes (Honauer et al. 2016).

A scene folder holds ``input_Cam000.png`` ... ``input_Cam080.png`` (9 x 9 views, view index
``9 * r + c``, row-major, so ``Cam040`` is the centre), ``gt_disp_lowres.pfm`` (disparity of the
centre view) and usually ``parameters.cfg`` (INI). The benchmark's disparity sign is the
convention of SPEC §1 with positions ``(c, r)``, so the ground truth is used unchanged.
"""

from __future__ import annotations

import configparser
import math
import os
import re
from pathlib import Path
from typing import Iterable

import numpy as np

from .._options import _is_real, int_pair, integer, number, path_like, shown
from .._paths import check_inside
from ..errors import DataNotFoundError, FormatError, InvalidInputError
from ..lightfield import LightField, centre_view
from .images import read_image, read_images_same_size
from .pfm import read_pfm

__all__ = ["read_hci_scene", "is_hci_scene", "HCI_LICENCE"]

HCI_LICENCE = "CC BY-NC-SA 4.0 (cite Honauer et al., ACCV 2016)"

#: Largest ``disparity_margin`` of :func:`read_hci_scene` (px): a wider range only adds labels
#: that no surface takes.
MAX_MARGIN = 1000.0

_CAM = re.compile(r"^input_Cam(\d{3})\.png$")


def is_hci_scene(folder: str | os.PathLike) -> bool:
    """True when ``folder`` (any path) is a folder holding ``input_Cam000.png``: an HCI 4D LF
    scene, as :func:`~hyperlf.formats.capture.is_capture` tells a capture.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from hyperlf.formats.images import write_image
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> is_hci_scene(folder)
    False
    >>> _ = write_image(folder / "input_Cam000.png", np.zeros((8, 10), dtype=np.uint8))
    >>> is_hci_scene(folder), is_hci_scene(folder / "input_Cam000.png")
    (True, False)
    """
    p = Path(path_like(folder, "folder", folder=None))
    return p.is_dir() and (p / "input_Cam000.png").is_file()


def _number(text: str):
    try:
        v = int(text)
    except ValueError:
        try:
            v = float(text)
        except ValueError:
            return text.strip()
    return v


def _read_cfg(path: Path) -> dict[str, dict[str, object]]:
    cp = configparser.ConfigParser(interpolation=None)  # values are raw text ("%" is fine)
    try:
        with open(path, encoding="utf-8") as fh:
            cp.read_file(fh)
    except (configparser.Error, UnicodeDecodeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FormatError(f"{path} is not a valid INI file ({first}); fix or remove it") from None
    return {s: {k: _number(v) for k, v in cp.items(s)} for s in cp.sections()}


#: View files are named ``input_Cam###.png`` (three digits), so a scene has at most 1000 views.
MAX_VIEWS = 1000


def _check_grid(R: int, C: int, where: str, err) -> tuple[int, int]:
    """Refuse grids that are not positive or hold more than :data:`MAX_VIEWS` views."""
    if R < 1 or C < 1 or R * C > MAX_VIEWS:
        raise err(f"{where} gives a {R} x {C} camera grid; an HCI scene has 1..{MAX_VIEWS} "
                  "views (input_Cam000..999), fix it or pass grid=(rows, cols)")
    return R, C


def _cfg_grid(cfg: dict, path: Path) -> tuple[int, int] | None:
    """``(num_cams_y, num_cams_x)`` from ``[extrinsics]``, validated; None when absent."""
    ext = cfg.get("extrinsics", {})
    nx, ny = ext.get("num_cams_x"), ext.get("num_cams_y")
    if nx is None and ny is None:
        return None
    if not all(isinstance(v, int) for v in (nx, ny)):
        raise FormatError(f"{path}: num_cams_x = {str(nx)[:20]!r} and num_cams_y = "
                          f"{str(ny)[:20]!r} must both be whole numbers; fix or remove them")
    return _check_grid(ny, nx, f"{path} (num_cams_y, num_cams_x)", FormatError)


def _grid_from(folder: Path, cfg: dict, grid) -> tuple[int, int]:
    if grid is not None:
        R, C = int_pair(grid, "grid", 1, what="(rows, cols)")
        return _check_grid(R, C, f"grid={shown(grid)}", InvalidInputError)
    from_cfg = _cfg_grid(cfg, folder / "parameters.cfg")
    if from_cfg is not None:
        return from_cfg
    idx = [int(m.group(1)) for f in os.listdir(folder) if (m := _CAM.match(f))]
    n = max(idx) + 1 if idx else 0
    s = math.isqrt(n)
    if s * s == n and s > 0:
        return s, s
    return 9, 9


def _select(sel: Iterable[int] | None, n: int, what: str) -> list[int]:
    """The indices ``sel`` into a grid axis of ``n`` cameras (None: all): distinct integers
    in ``0..n - 1`` (an integral float such as ``2.0`` is taken, ``2.7`` is not)."""
    if sel is None:
        return list(range(n))
    try:
        out = [integer(v, what, maximum=n - 1) for v in sel]
    except (TypeError, InvalidInputError):
        out = None
    if not out or len(set(out)) != len(out):
        raise InvalidInputError(f"{what} must be distinct indices in 0..{n - 1}, got "
                                f"{shown(sel)}")
    return out


def read_hci_scene(folder: str | os.PathLike, *, grid=None, rows=None, cols=None,
                   disparity_margin: float = 0.5) -> LightField:
    """Load an HCI 4D light field benchmark scene as an RGB :class:`LightField`.

    Parameters
    ----------
    folder : path-like
        Scene folder with ``input_Cam###.png`` views.
    grid : (int, int), optional
        ``(rows, cols)`` of the full camera grid. Default: ``[extrinsics] num_cams_y/x`` from
        ``parameters.cfg``, else the square number of ``input_Cam`` files, else 9 x 9.
    rows, cols : sequence of int, optional
        Sub-grid to load (indices into the full grid), e.g. ``rows=range(2, 7),
        cols=range(2, 8)`` for a 5 x 6 array. Default: all.
    disparity_margin : float
        Margin (px) added on both sides of the disparity range, beyond the whole pixels
        around the scene's extremes; 0 to :data:`MAX_MARGIN`.

    Returns
    -------
    LightField
        ``views`` float32 ``(R, C, H, W, 3)``: the sRGB-encoded values as stored, scaled to
        [0, 1] (``metadata["encoding"] = "srgb"``; not linearised). ``positions[r, c]`` is
        ``(c, r)`` of the **original** grid. The reference is the centre camera (``Cam040`` for
        9 x 9) when it is in the sub-grid, else the sub-grid's default centre.
        ``gt_disparity`` (H, W) is ``gt_disp_lowres.pfm``, attached only when the reference is
        the centre camera. ``wavelengths`` is None.
        ``disparity_range``: ``(floor(lo) - margin, ceil(hi) + margin)``, where ``lo, hi`` are
        ``[meta] disp_min/disp_max`` from ``parameters.cfg`` when present, otherwise the
        ground truth's extremes; None without either (the cfg's values are the scene's
        extremes rounded to 0.1 px, so they are widened like the ground truth's). The other
        ``parameters.cfg`` entries are in ``metadata["hci_parameters"]`` (section -> key ->
        value).

    Raises
    ------
    DataNotFoundError
        When the folder or any selected view is missing (all missing files are named).
    FormatError
        When a file cannot be decoded or views differ in size.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from hyperlf.formats.images import write_image
    >>> from hyperlf.formats.pfm import write_pfm
    >>> folder = pathlib.Path(tempfile.mkdtemp()) / "tiny"
    >>> folder.mkdir()
    >>> rgb = np.random.default_rng(0).integers(0, 256, (3, 3, 8, 10, 3), dtype=np.uint8)
    >>> for i in range(9):                          # a 3 x 3 grid, view index 3 * r + c
    ...     _ = write_image(folder / f"input_Cam{i:03d}.png", rgb[i // 3, i % 3])
    >>> _ = write_pfm(folder / "gt_disp_lowres.pfm", np.full((8, 10), 1.25, dtype=np.float32))
    >>> lf = read_hci_scene(folder)
    >>> lf.views.shape, lf.reference, lf.metadata["centre_view"]
    ((3, 3, 8, 10, 3), (1, 1), 'input_Cam004.png')
    >>> bool(np.allclose(lf.views, rgb / 255))      # sRGB values scaled to [0, 1]
    True
    >>> lf.positions[2, 1].tolist(), float(lf.gt_disparity[0, 0]), lf.disparity_range
    ([1.0, 2.0], 1.25, (0.5, 2.5))
    >>> sub = read_hci_scene(folder, rows=[0, 1], cols=[1, 2])      # a 2 x 2 corner
    >>> sub.views.shape, sub.reference, sub.gt_disparity is None    # the centre is view (1, 0)
    ((2, 2, 8, 10, 3), (1, 0), False)
    """
    root = Path(path_like(folder, "folder", folder=None))
    disparity_margin = number(disparity_margin, "disparity_margin", at_most=MAX_MARGIN)
    if not root.is_dir():
        raise DataNotFoundError(f"HCI scene folder {root} does not exist")
    cfg_path = root / "parameters.cfg"
    check_inside(root, [cfg_path], "HCI scene")
    cfg = _read_cfg(cfg_path) if cfg_path.is_file() else {}
    R, C = _grid_from(root, cfg, grid)
    rsel = _select(rows, R, "rows")
    csel = _select(cols, C, "cols")
    flat = _view_files(root, C, rsel, csel)
    gt_path = root / "gt_disp_lowres.pfm"
    check_inside(root, [*flat, gt_path], "HCI scene")
    views = read_images_same_size(flat, lambda f: read_image(f, as_float=True, channels="rgb"),
                                  f"HCI scene {root}")
    views = views.reshape(len(rsel), len(csel), *views.shape[1:])

    cc, rr = np.meshgrid(np.asarray(csel, float), np.asarray(rsel, float))
    positions = np.stack([cc, rr], axis=-1)
    centre = centre_view(R, C)
    centre_in = centre[0] in rsel and centre[1] in csel
    reference = (rsel.index(centre[0]), csel.index(centre[1])) if centre_in else None
    gt = _ground_truth(gt_path, views.shape[2:4])
    disparity_range = _disparity_range(cfg, gt, disparity_margin)

    metadata = {
        "source": "HCI 4D light field benchmark",
        "scene": root.name,
        "licence": HCI_LICENCE,
        "encoding": "srgb",
        "full_grid": [R, C],
        "rows": rsel,
        "cols": csel,
        "centre_view": f"input_Cam{C * centre[0] + centre[1]:03d}.png",
    }
    if gt is not None and not centre_in:
        metadata["gt_note"] = "gt_disp_lowres.pfm not attached: the centre view is not loaded"
    if cfg:
        metadata["hci_parameters"] = cfg
    return LightField(
        views=views,
        positions=positions,
        reference=reference,
        disparity_range=disparity_range,
        gt_disparity=gt if centre_in else None,
        metadata=metadata,
    )


def _view_files(root: Path, C: int, rsel: list, csel: list) -> list[Path]:
    """The sub-grid's view files in raster order; every missing one named in one refusal."""
    files = [root / f"input_Cam{C * r + c:03d}.png" for r in rsel for c in csel]
    missing = [f.name for f in files if not f.is_file()]
    if missing:
        more = f" and {len(missing) - 8} more" if len(missing) > 8 else ""
        raise DataNotFoundError(
            f"HCI scene {root} is missing {len(missing)} view(s): {', '.join(missing[:8])}{more}; "
            "download the complete scene, or load a sub-grid (hyperlf synth hci --grid R,C; "
            "read_hci_scene(rows=, cols=) in Python)"
        )
    return files


def _ground_truth(gt_path: Path, shape: tuple[int, int]) -> np.ndarray | None:
    """``gt_disp_lowres.pfm`` where the scene has it, of the views' ``shape``."""
    if not gt_path.is_file():
        return None
    gt = read_pfm(gt_path)
    if gt.ndim != 2 or gt.shape != shape:
        raise FormatError(
            f"{gt_path} has shape {gt.shape} but the views are {shape}; "
            "use the lowres ground truth that matches the input views"
        )
    return gt


def _disparity_range(cfg: dict, gt: np.ndarray | None, margin: float):
    """The scene's extreme disparities, widened to whole pixels and by ``margin``:
    ``[meta] disp_min/disp_max`` of ``parameters.cfg`` when it gives a finite pair, else the
    ground truth's extremes, else None.

    The benchmark writes ``disp_min`` / ``disp_max`` as the scene's extremes rounded to 0.1 px,
    so its nearest and farthest surfaces lie on (or up to 0.05 px beyond) them.  Taken as
    they are, they would put those surfaces on the end labels of a depth run, where the
    sub-pixel fit has one side only and the end label wins weakly textured pixels (full
    antinous with its own extremes as the range: BadPix(0.07) 5.58 % against 4.46 % with the
    widened range; BENCHMARKS.md, sixty-sixth session).  Both sources are therefore widened
    alike."""
    meta = cfg.get("meta", {})
    dmin, dmax = meta.get("disp_min"), meta.get("disp_max")
    if _is_real(dmin) and _is_real(dmax) and dmin < dmax:
        lo, hi = float(dmin), float(dmax)
    elif gt is not None and np.isfinite(gt).any():
        ok = gt[np.isfinite(gt)]
        lo, hi = float(ok.min()), float(ok.max())
    else:
        return None
    return math.floor(lo) - margin, math.ceil(hi) + margin
