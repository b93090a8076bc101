"""Middlebury stereo pairs: the v2 layout (Tsukuba, Teddy, Venus) and the 2005 layout (Art).

v2 layout: ``imL.png``, ``imR.png``, ``groundtruth.png`` (disparity times ``scale``, 0 =
unknown), ``info.txt`` (two lines: scale, max disparity) and optional evaluation masks
``all.png``, ``nonocc.png``, ``disc.png`` (255 = evaluated; 128 in ``disc`` = occluded).

2005 layout (``<name>1.png`` left, ``<name>5.png`` right, ``<name>1_true.png`` ground truth,
channel 0): the scale is not in the folder. For the half-size sets shipped here it is 2 (the
ground truth holds full-resolution disparities); pass ``scale=`` for other sizes.

Disparity sign: the right view is at ``px = +1``, a left pixel ``x`` matches right pixel
``x - d`` (SPEC §1, §4).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._atomic import atomic_write_text
from .._paths import check_inside
from .._options import integer, mapping, number, path_like, real_array, shown, text
from ..errors import DataNotFoundError, FormatError, InvalidInputError
from .images import read_image, write_image

__all__ = ["StereoPair", "read_middlebury", "write_middlebury", "MASK_NAMES"]

MASK_NAMES = ("all", "nonocc", "disc")
_DEFAULT_2005_SCALE = 2.0


@dataclass
class StereoPair:
    """A rectified stereo pair with ground truth.

    Attributes
    ----------
    left, right : ndarray of float32, shape (H, W, 3)
        RGB images in [0, 1] (values as stored, sRGB-encoded).
    gt_disparity : ndarray of float32, shape (H, W)
        Disparity of the left view in pixels (file value / ``scale``); NaN where unknown.
    masks : dict of str -> ndarray of bool, shape (H, W)
        Evaluation masks present in the folder (``all``, ``nonocc``, ``disc``): True where the
        pixel is evaluated (value 255). Empty when the scene has none.
    scale : float
        Factor the ground-truth file's integers were divided by.
    max_disparity : int
        Search bound of the disparities: v2 takes it from ``info.txt`` (documented as "disparities
        range in [0, max - 1]", but Venus' ground truth reaches 19.75 with max 19, so treat it as
        approximate); 2005 uses ``ceil(max gt) + 1``.
    name : str
        Scene name (the folder's name).
    metadata : dict
        Provenance.
    """

    left: np.ndarray
    right: np.ndarray
    gt_disparity: np.ndarray
    masks: dict = field(default_factory=dict)
    scale: float = 1.0
    max_disparity: int = 0
    name: str = ""
    metadata: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        """Shapes and options checked (O(1): the arrays are not scanned)."""
        left, right = (real_array(v, k, None) for v, k in ((self.left, "left"),
                                                            (self.right, "right")))
        gt = real_array(self.gt_disparity, "gt_disparity", None)
        for a, label in ((left, "left"), (right, "right"), (gt, "gt_disparity")):
            if a.dtype.kind not in "biuf" or a.size == 0:
                raise InvalidInputError(f"{label} must be a non-empty array of numbers, got "
                                        f"{shown(getattr(self, label))}")
        if left.ndim not in (2, 3) or right.shape != left.shape or gt.shape != left.shape[:2]:
            raise InvalidInputError(f"left and right must be (H, W[, 3]) images of one shape "
                                    f"and gt_disparity (H, W); got {left.shape}, {right.shape} "
                                    f"and {gt.shape}")
        mapping(self.masks, "masks", optional=False)
        if not all(isinstance(k, str) for k in self.masks):
            raise InvalidInputError(f"masks must be named by text, got {list(self.masks)!r:.60}")
        self.scale = number(self.scale, "scale", positive=True)
        self.max_disparity = integer(self.max_disparity, "max_disparity")
        text(self.name, "name")
        mapping(self.metadata, "metadata", optional=False)

    @property
    def valid(self) -> np.ndarray:
        """Pixels with known ground truth, shape (H, W)."""
        return np.isfinite(self.gt_disparity)

    @property
    def search_range(self) -> tuple[int, int]:
        """``(0, dmax)``, the disparities Table 1 searches: ``max_disparity`` widened to
        reach the ground truth's largest value (Venus's reaches 19.75 with a maximum of 19)."""
        known = self.gt_disparity[self.valid]
        top = int(math.ceil(float(known.max()))) if known.size else 0
        return 0, max(int(self.max_disparity), top)

    def eval_mask(self, name: str = "all") -> np.ndarray:
        """The named mask and known ground truth, or just known ground truth if absent."""
        if not isinstance(name, str):
            raise InvalidInputError(f"name must be a mask's name (text), got {shown(name)}")
        m = self.masks.get(name)
        return self.valid if m is None else (m & self.valid)


def _grey(path: Path) -> np.ndarray:
    a = read_image(path, as_float=False)
    return a[..., 0] if a.ndim == 3 else a


def _read_info(path: Path) -> tuple[float, int]:
    try:
        tokens = path.read_text(encoding="utf-8").split()
        scale, maxd = float(tokens[0]), int(float(tokens[1]))
    except (OSError, UnicodeDecodeError, IndexError, ValueError):
        raise FormatError(
            f"{path} must hold two numbers, the ground-truth scale and the max disparity, "
            "one per line (e.g. '16' then '15')"
        ) from None
    if not (math.isfinite(scale) and scale > 0 and maxd > 0):
        raise FormatError(f"{path}: scale and max disparity must be positive, got {scale}, {maxd}")
    return scale, maxd


def _check_same(name: str, ref: np.ndarray, other: np.ndarray, what: str) -> None:
    if other.shape[:2] != ref.shape[:2]:
        raise FormatError(
            f"Middlebury scene {name}: {what} is {other.shape[1]} x {other.shape[0]} px but the "
            f"left image is {ref.shape[1]} x {ref.shape[0]}"
        )


def read_middlebury(folder: str | os.PathLike, scale: float | None = None) -> StereoPair:
    """Load a Middlebury scene folder (v2 or 2005 layout).

    Parameters
    ----------
    folder : path-like
        The scene folder.
    scale : float, optional
        Override the ground-truth scale (v2: from ``info.txt``; 2005: default 2, the half-size
        factor).

    Returns
    -------
    StereoPair

    Raises
    ------
    DataNotFoundError
        When the folder or a required file is missing.
    FormatError
        When a file is malformed or sizes disagree.
    InvalidInputError
        When a file of the scene leads outside its folder (a symlink), before any is read.
    """
    root = Path(path_like(folder, "folder", folder=None))
    scale = number(scale, "scale", optional=True, at_least=1e-6, at_most=1e6)
    if not root.is_dir():
        raise DataNotFoundError(f"Middlebury scene folder {root} does not exist")
    v2 = (root / "imL.png").is_file() or (root / "groundtruth.png").is_file()
    left, right, raw, masks, s, maxd, layout, files, name = (
        _read_v2 if v2 else _read_2005)(root, scale)
    if not (math.isfinite(s) and s > 0):
        raise InvalidInputError(f"scale must be positive, got {scale}")
    _check_same(name, left, right, files[1])
    _check_same(name, left, raw, files[2])
    gt = raw.astype(np.float32) / np.float32(s)
    gt[raw == 0] = np.nan
    if maxd is None:
        maxd = int(math.ceil(float(np.nanmax(gt)))) + 1 if np.isfinite(gt).any() else 1
    return StereoPair(
        left=left, right=right, gt_disparity=gt, masks=masks, scale=s, max_disparity=int(maxd),
        name=name,
        metadata={"source": "Middlebury stereo", "layout": layout, "folder": str(root),
                  "files": list(files), "encoding": "srgb"},
    )


def _read_v2(root: Path, scale: float | None) -> tuple:
    """A v2 scene (``imL``, ``imR``, ``groundtruth``, ``info.txt``, masks): ``(left, right,
    raw ground truth, masks, scale, max disparity, layout, files, name)``."""
    need = ["imL.png", "imR.png", "groundtruth.png", "info.txt"]
    missing = [f for f in need if not (root / f).is_file()]
    if missing:
        raise DataNotFoundError(
            f"Middlebury v2 scene {root} is missing {', '.join(missing)}"
        )
    check_inside(root, [root / f for f in (*need, *(f"{m}.png" for m in MASK_NAMES))],
                 "Middlebury scene")
    file_scale, maxd = _read_info(root / "info.txt")
    s = float(scale) if scale is not None else file_scale
    left = read_image(root / "imL.png", channels="rgb")
    right = read_image(root / "imR.png", channels="rgb")
    raw = _grey(root / "groundtruth.png")
    masks = {}
    for m in MASK_NAMES:
        if (root / f"{m}.png").is_file():
            mk = _grey(root / f"{m}.png")
            _check_same(root.name, left, mk, f"{m}.png")
            masks[m] = mk == 255
    return (left, right, raw, masks, s, maxd, "v2", ("imL.png", "imR.png", "groundtruth.png"),
            root.name)


def _read_2005(root: Path, scale: float | None) -> tuple:
    """A 2005 scene (``<name>1``, ``<name>5``, ``<name>1_true``), as :func:`_read_v2`."""
    cands = sorted(f for f in os.listdir(root) if re.fullmatch(r".+1_true\.png", f))
    if not cands:
        raise DataNotFoundError(
            f"{root} is not a Middlebury scene: expected imL.png/imR.png/groundtruth.png/"
            "info.txt (v2) or <name>1.png/<name>5.png/<name>1_true.png (2005)"
        )
    stem = cands[0][: -len("1_true.png")]
    need = [f"{stem}1.png", f"{stem}5.png", f"{stem}1_true.png"]
    missing = [f for f in need if not (root / f).is_file()]
    if missing:
        raise DataNotFoundError(f"Middlebury 2005 scene {root} is missing {', '.join(missing)}")
    check_inside(root, [root / f for f in need], "Middlebury scene")
    s = float(scale) if scale is not None else _DEFAULT_2005_SCALE
    left = read_image(root / need[0], channels="rgb")
    right = read_image(root / need[1], channels="rgb")
    raw = _grey(root / need[2])
    return left, right, raw, {}, s, None, "2005", tuple(need), stem or root.name


def write_middlebury(folder: str | os.PathLike, pair: StereoPair) -> Path:
    """Write a :class:`StereoPair` in the v2 layout (each file atomically; ``info.txt`` last).

    Images are written as 8-bit RGB PNG, the ground truth as ``round(d * scale)`` in an 8-bit
    grey PNG (NaN -> 0), masks as 0/255 grey PNGs.

    Parameters
    ----------
    folder : path-like
        Target folder (created).
    pair : StereoPair
        What to write.

    Returns
    -------
    Path
        The folder.

    Raises
    ------
    InvalidInputError
        When the scaled ground truth does not fit into 1..255.
    """
    root = Path(path_like(folder, "folder", folder=True))
    if not isinstance(pair, StereoPair):
        raise InvalidInputError(f"pair must be a StereoPair, got {type(pair).__name__}")
    s = number(pair.scale, "pair.scale", positive=True)
    gt = real_array(pair.gt_disparity, "pair.gt_disparity")
    mapping(pair.masks, "pair.masks", optional=False)
    known = np.isfinite(gt)
    q = np.zeros(gt.shape, dtype=np.float64)
    q[known] = np.rint(gt[known] * s)
    if np.any(q[known] < 1) or np.any(q > 255):
        raise InvalidInputError(
            f"ground truth times scale {s:g} must lie in 1..255 to fit an 8-bit PNG "
            "(0 means unknown); choose a smaller scale"
        )
    root.mkdir(parents=True, exist_ok=True)
    write_image(root / "imL.png", np.asarray(pair.left), bit_depth=8)
    write_image(root / "imR.png", np.asarray(pair.right), bit_depth=8)
    write_image(root / "groundtruth.png", q.astype(np.uint8))
    for m, mask in pair.masks.items():
        write_image(root / f"{m}.png", np.where(np.asarray(mask, bool), 255, 0).astype(np.uint8))
    atomic_write_text(root / "info.txt", f"{s:g}\n{int(pair.max_disparity)}\n")
    return root
