"""Evaluation metrics (SPEC §9).

Disparity: bad-tau (%), RMSE, MSE x 100, BadPix(0.07) as in the HCI 4D light field benchmark
(15-pixel border excluded). Cube: PSNR (per band and overall), spectral angle (SAM, degrees) and
the fraction of entries completed.

Every disparity metric is evaluated on a mask, and the mask is part of the result so tables can
name it. Pixels whose ground truth is not finite (NaN/inf: unknown) are never evaluated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _options as _opt
from .errors import InvalidInputError

__all__ = [
    "evaluation_mask",
    "bad_pixels",
    "BadPixelShare",
    "bad_pixel_breakdown",
    "rmse",
    "mse_x100",
    "badpix",
    "DisparityScores",
    "disparity_scores",
    "hci_scores",
    "at_range_limit",
    "range_limit_shares",
    "psnr",
    "psnr_per_band",
    "sam",
    "cube_scores",
    "completion_ratio",
    "HCI_BORDER",
]

#: Border excluded by the HCI benchmark's metrics (``boundary_offset``), pixels.
HCI_BORDER = 15


def _pair(estimate, truth) -> tuple[np.ndarray, np.ndarray]:
    est = _opt.real_array(estimate, "estimate")
    gt = _opt.real_array(truth, "truth")
    if est.shape != gt.shape:
        hint = ("; a light field's gt_disparity holds every view's: compare with its "
                "reference_gt_disparity" if gt.ndim == 4 and gt.shape[2:] == est.shape else "")
        raise InvalidInputError(f"estimate has shape {est.shape} but ground truth has "
                                f"{gt.shape}; they must match{hint}")
    return est, gt


def evaluation_mask(truth: np.ndarray, mask: np.ndarray | None = None,
                    *, border: int = 0) -> np.ndarray:
    """Pixels to evaluate: finite ground truth, inside ``mask``, outside a ``border``.

    Parameters
    ----------
    truth : ndarray, shape (H, W)
        Ground truth; non-finite values mean "unknown".
    mask : ndarray of bool, shape (H, W), optional
        Extra mask (e.g. Middlebury's ``all`` or ``nonocc``).
    border : int
        Width in pixels of a frame excluded on every side (HCI: 15).

    Returns
    -------
    ndarray of bool, shape (H, W)
        True where a pixel is evaluated.

    Examples
    --------
    >>> gt = np.array([[0.0, np.nan], [1.0, 2.0]])
    >>> evaluation_mask(gt).tolist()
    [[True, False], [True, True]]
    """
    gt = _opt.real_array(truth, "truth")
    border = _opt.integer(border, "border")
    m = np.isfinite(gt)
    if mask is not None:
        m &= _opt.bool_mask(mask, "mask", gt.shape)
    if border > 0:
        frame = np.zeros_like(m)
        frame[border:-border, border:-border] = True
        m &= frame
    return m


def _axis(band_axis, cube: np.ndarray) -> int:
    """``band_axis`` as an axis of ``cube`` (negative ones count from the end)."""
    return _opt.integer(band_axis, "band_axis", -cube.ndim, maximum=cube.ndim - 1)


def _masked_error(estimate, truth, mask, border) -> np.ndarray:
    est, gt = _pair(estimate, truth)
    m = evaluation_mask(gt, mask, border=border)
    if not m.any():
        raise InvalidInputError("no pixel to evaluate: the mask (and border) exclude everything")
    err = est[m] - gt[m]
    # A missing estimate (NaN) counts as an infinitely bad pixel, never as a skipped one.
    return np.where(np.isfinite(err), err, np.inf)


def bad_pixels(estimate, truth, tau: float, *, mask=None, border: int = 0) -> float:
    """Percentage of evaluated pixels with ``|estimate - truth| > tau`` (bad-tau, %).

    Parameters
    ----------
    estimate, truth : array_like
        Estimated and true disparity, same shape (px). A non-finite estimate counts as an
        infinitely bad pixel; non-finite ground truth is not evaluated.
    mask : array_like of bool, optional
        Extra evaluation mask (:func:`evaluation_mask`).
    border : int
        Frame excluded on every side, pixels.
    tau : float
        Error threshold, px.

    Returns
    -------
    float
        Bad pixels, % of the evaluated pixels.

    Examples
    --------
    >>> bad_pixels([[0.0, 1.0]], [[0.0, 0.0]], tau=0.5)
    50.0
    """
    tau = _opt.number(tau, "tau")
    err = _masked_error(estimate, truth, mask, border)
    return float(100.0 * np.mean(np.abs(err) > tau))


class _Record:
    """A result whose fields read as a dict (for JSON reports)."""

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass(frozen=True)
class BadPixelShare(_Record):
    """One class of pixels in :func:`bad_pixel_breakdown`, every field in % of all evaluated
    pixels (so that the classes of a partition add up to the whole).

    Attributes
    ----------
    share : float
        The class's evaluated pixels.
    bad : float
        Its bad pixels: ``too_large + too_small + missing``.
    too_large, too_small : float
        Its bad pixels whose estimate exceeds the truth by more than ``tau`` (a nearer
        surface: a fattened foreground), or falls short of it by more than ``tau``.
    missing : float
        Its pixels without a finite estimate (always bad).
    """

    share: float
    bad: float
    too_large: float
    too_small: float
    missing: float


def bad_pixel_breakdown(estimate, truth, tau: float, classes, *, mask=None,
                        border: int = 0) -> dict[str, BadPixelShare]:
    """Where bad-tau's points lie: per named class of pixels, its share of the evaluated pixels
    and its bad pixels, by the sign of their error.

    For a failure analysis: the classes may be, for a rectified pair, the pixels the other
    camera sees, those it does not and those whose match leaves its image, each split by
    whether the left-right check kept the estimate.  Every figure is a percentage of *all*
    evaluated pixels (:func:`evaluation_mask`), so a partition's ``bad`` figures add up to
    :func:`bad_pixels`; classes may also overlap or leave pixels out.

    Parameters
    ----------
    estimate, truth : array_like
        Estimated and true disparity, same shape (px), as for :func:`bad_pixels`.
    tau : float
        Error threshold, px.
    classes : mapping of str to array_like of bool
        The classes, each a boolean map of the disparity's shape.
    mask : array_like of bool, optional
        Extra evaluation mask (:func:`evaluation_mask`).
    border : int
        Frame excluded on every side, pixels.

    Returns
    -------
    dict of str to BadPixelShare
        In the order of ``classes``.

    Examples
    --------
    >>> est, gt = np.array([[0.0, 9.0, 0.0, 1.0]]), np.zeros((1, 4))
    >>> left = np.array([[True, True, False, False]])
    >>> b = bad_pixel_breakdown(est, gt, 5.0, {"left": left, "right": ~left})
    >>> b["left"].share, b["left"].too_large, b["right"].bad
    (50.0, 25.0, 0.0)
    """
    est, gt = _pair(estimate, truth)
    tau = _opt.number(tau, "tau")
    classes = _opt.mapping(classes, "classes", optional=False)
    m = evaluation_mask(gt, mask, border=border)
    n = int(m.sum())
    if n == 0:
        raise InvalidInputError("no pixel to evaluate: the mask (and border) exclude everything")
    finite = np.isfinite(est)
    with np.errstate(invalid="ignore"):
        err = np.where(finite, est - gt, 0.0)
    kinds = {"too_large": err > tau, "too_small": err < -tau, "missing": ~finite}
    out = {}
    for name, cls in classes.items():
        name = _opt.text(name, "a class's name")
        sel = m & _opt.bool_mask(cls, f"class {name!r}", gt.shape)
        counts = {k: 100.0 * int((sel & v).sum()) / n for k, v in kinds.items()}
        out[name] = BadPixelShare(share=100.0 * int(sel.sum()) / n, bad=sum(counts.values()),
                                  **counts)
    return out


def rmse(estimate, truth, *, mask=None, border: int = 0) -> float:
    """Root-mean-square disparity error (px) over evaluated pixels.

    Parameters
    ----------
    estimate, truth, mask, border
        As in :func:`bad_pixels`.

    Returns
    -------
    float
        RMSE in px.

    Examples
    --------
    >>> rmse([[3.0, 4.0]], [[0.0, 0.0]])  # sqrt((9 + 16) / 2)
    3.5355339059327378
    """
    err = _masked_error(estimate, truth, mask, border)
    return float(np.sqrt(np.mean(err ** 2)))


def mse_x100(estimate, truth, *, mask=None, border: int = 0) -> float:
    """Mean squared error times 100, ``100 * mean(error ** 2)`` (px squared), as the HCI
    benchmark reports it (reference at :func:`badpix`); parameters and evaluated pixels as in
    :func:`rmse`.

    Examples
    --------
    >>> mse_x100([[0.1, 0.0]], [[0.0, 0.0]])
    0.5000000000000001
    """
    err = _masked_error(estimate, truth, mask, border)
    return float(100.0 * np.mean(err ** 2))


def badpix(estimate, truth, threshold: float = 0.07, *, mask=None,
           border: int = HCI_BORDER) -> float:
    """HCI BadPix(threshold): % of pixels with error above ``threshold`` (default 0.07 px),
    excluding the benchmark's 15-pixel border.

    Parameters
    ----------
    estimate, truth, mask
        As in :func:`bad_pixels`.
    threshold : float
        Error threshold, px (HCI: 0.07).
    border : int
        Frame excluded on every side (default :data:`HCI_BORDER`).

    Returns
    -------
    float
        Bad pixels, % of the pixels inside the border.

    References
    ----------
    K. Honauer, O. Johannsen, D. Kondermann, B. Goldluecke, "A dataset and evaluation
    methodology for depth estimation on 4D light fields", ACCV 2016.

    Examples
    --------
    >>> gt = np.zeros((40, 40)); est = gt.copy(); est[20, 20] = 1.0
    >>> round(badpix(est, gt), 4)  # one bad pixel among the 10 x 10 inside the border
    1.0
    """
    return bad_pixels(estimate, truth, threshold, mask=mask, border=border)


@dataclass(frozen=True)
class DisparityScores(_Record):
    """Disparity metrics on one mask (percentages in %, errors in px).

    Attributes
    ----------
    rmse, mse_x100 : float
        Root-mean-square error (px) and mean squared error x 100.
    badpix_007, bad_0_5, bad_1, bad_2, bad_5 : float
        Percentage of pixels whose error exceeds 0.07, 0.5, 1, 2 and 5 px.
    n_pixels : int
        Number of evaluated pixels.
    mask : str
        Name of the evaluation mask.
    border : int
        Frame excluded on every side, pixels.
    """

    rmse: float
    mse_x100: float
    badpix_007: float
    bad_0_5: float
    bad_1: float
    bad_2: float
    bad_5: float
    n_pixels: int
    mask: str
    border: int


def disparity_scores(estimate, truth, *, mask=None, mask_name: str = "all",
                     border: int = 0) -> DisparityScores:
    """All disparity metrics at once on one mask.

    BadPix(0.07) uses the same ``border`` as the rest here, so all numbers of a row refer to
    the same pixels; pass ``border=HCI_BORDER`` for the HCI protocol.

    Parameters
    ----------
    estimate, truth : array_like
        Estimated and true disparity, same shape (px).
    mask : array_like of bool, optional
        Extra evaluation mask.
    mask_name : str
        Name recorded in the result (e.g. Middlebury's ``"all"``).
    border : int
        Frame excluded on every side, pixels.

    Returns
    -------
    DisparityScores

    Examples
    --------
    >>> s = disparity_scores([[0.0, 1.0]], [[0.0, 0.0]])
    >>> s.rmse, s.bad_0_5, s.n_pixels
    (0.7071067811865476, 50.0, 2)
    """
    _opt.text(mask_name, "mask_name")
    err = np.abs(_masked_error(estimate, truth, mask, border))
    return DisparityScores(
        rmse=float(np.sqrt(np.mean(err ** 2))),
        mse_x100=float(100.0 * np.mean(err ** 2)),
        badpix_007=float(100.0 * np.mean(err > 0.07)),
        bad_0_5=float(100.0 * np.mean(err > 0.5)),
        bad_1=float(100.0 * np.mean(err > 1.0)),
        bad_2=float(100.0 * np.mean(err > 2.0)),
        bad_5=float(100.0 * np.mean(err > 5.0)),
        n_pixels=int(err.size),
        mask=mask_name,
        border=border,
    )


def hci_scores(estimate, truth) -> DisparityScores | None:
    """:func:`disparity_scores` with the HCI protocol's border (:data:`HCI_BORDER`), or None
    when the maps are too small to keep a pixel inside it.

    Examples
    --------
    A constant error of 0.25 px everywhere, and a gross one only in the top 15 rows, which
    the border leaves out: the RMSE is the offset, over the (40 - 30) x (50 - 30) pixels
    inside the border.

    >>> truth = np.zeros((40, 50))
    >>> est = truth + 0.25
    >>> est[:15] = 9.0
    >>> s = hci_scores(est, truth)
    >>> s.rmse, s.bad_0_5, s.n_pixels
    (0.25, 0.0, 200)
    >>> hci_scores(np.zeros((30, 30)), np.zeros((30, 30))) is None  # nothing inside the border
    True
    """
    shape = np.shape(_opt.real_array(truth, "truth"))
    if len(shape) != 2:
        raise InvalidInputError(f"truth must be a 2-D disparity map, got shape {shape}")
    if min(shape) <= 2 * HCI_BORDER:
        return None
    return disparity_scores(estimate, truth, border=HCI_BORDER, mask_name="all-15px-border")


def at_range_limit(disparity, disparity_range, tol: float = 1e-3) -> np.ndarray:
    """Pixels whose disparity sits at either end of ``disparity_range`` (within ``tol``): the
    labels a cost minimum lands on by chance where nothing can be matched.

    Examples
    --------
    >>> at_range_limit([[-2.0, 0.3, 2.0]], (-2, 2)).tolist()
    [[True, False, True]]
    """
    d = _opt.real_array(disparity, "disparity")
    lo, hi = _opt.real_pair(disparity_range, "disparity_range", "(low, high), finite")
    tol = _opt.number(tol, "tol")
    return (np.abs(d - lo) < tol) | (np.abs(d - hi) < tol)


def range_limit_shares(disparity, disparity_range, mask=None) -> tuple[float, float] | None:
    """Percentages of the (``mask``'s finite) pixels at the low and at the high end of
    ``disparity_range`` (:func:`at_range_limit`); None when no pixel is left.

    Examples
    --------
    >>> range_limit_shares([[-2.0, 0.3, 2.0, 2.0]], (-2, 2))
    (25.0, 50.0)
    """
    d = _opt.real_array(disparity, "disparity")
    lo, hi = _opt.real_pair(disparity_range, "disparity_range", "(low, high), finite")
    ok = np.isfinite(d)
    if mask is not None:
        ok &= _opt.bool_mask(mask, "mask", d.shape, broadcast=True)
    if not ok.any():
        return None
    return (100.0 * float(np.mean(at_range_limit(d[ok], (lo, lo)))),
            100.0 * float(np.mean(at_range_limit(d[ok], (hi, hi)))))


def psnr(estimate, truth, *, data_range: float = 1.0, mask=None) -> float:
    """Peak signal-to-noise ratio (dB) over all (masked) entries.

    Parameters
    ----------
    estimate, truth : array_like
        Same shape.
    data_range : float
        The peak value (1.0 for intensities in [0, 1]).
    mask : array_like of bool, optional
        Broadcast to the inputs' shape; selects the entries compared.

    Returns
    -------
    float
        PSNR in dB; ``inf`` for identical inputs.

    Examples
    --------
    >>> psnr(np.full(4, 0.1), np.zeros(4))
    20.0
    """
    est, gt = _pair(estimate, truth)
    data_range = _opt.number(data_range, "data_range", positive=True)
    if mask is not None:
        m = _opt.bool_mask(mask, "mask", gt.shape, broadcast=True)
        if not m.any():
            raise InvalidInputError("psnr: the mask excludes every entry")
        est, gt = est[m], gt[m]
    return _psnr_of_mse(float(np.mean((est - gt) ** 2)), data_range)


def _psnr_of_mse(mse: float, data_range: float) -> float:
    if mse == 0:
        return float("inf")
    return float(20.0 * np.log10(data_range) - 10.0 * np.log10(mse))  # no overflow of range²


def psnr_per_band(estimate, truth, *, band_axis: int = -3, data_range: float = 1.0,
                  mask=None) -> np.ndarray:
    """PSNR (dB) of every band of a cube.

    Parameters
    ----------
    estimate, truth, band_axis
        As in :func:`sam`.
    data_range, mask
        As in :func:`psnr`.

    Returns
    -------
    ndarray, shape (B,)
        PSNR of every band, dB.

    Examples
    --------
    Three bands (axis -3) off by 0.1, 0.01 and nothing: ``-10 log10(e**2)`` gives 20 dB,
    40 dB and infinity.

    >>> truth = np.zeros((3, 4, 5))
    >>> est = truth + np.array([0.1, 0.01, 0.0])[:, None, None]
    >>> psnr_per_band(est, truth).round(3).tolist()
    [20.0, 40.0, inf]
    """
    est, gt = _pair(estimate, truth)
    band_axis = _axis(band_axis, est)
    m = None if mask is None else np.moveaxis(
        _opt.bool_mask(mask, "mask", gt.shape, broadcast=True), band_axis, 0)
    est = np.moveaxis(est, band_axis, 0)
    gt = np.moveaxis(gt, band_axis, 0)
    return np.array([psnr(est[b], gt[b], data_range=data_range,
                          mask=None if m is None else m[b])
                     for b in range(est.shape[0])])


def sam(estimate, truth, *, band_axis: int = -3, mask=None, eps: float = 1e-12) -> float:
    """Mean spectral angle (degrees) between estimated and true spectra.

    Spectra run along ``band_axis``; every other position is one spectrum. ``mask`` (shape of
    one band, i.e. the array without ``band_axis``) selects spectra. Spectra whose norm is
    zero in either input are skipped.

    Parameters
    ----------
    estimate, truth : array_like
        Cubes of the same shape.
    band_axis : int
        Axis of the bands (default -3 for ``[..., B, H, W]``).
    mask : array_like of bool, optional
        Shape of the cube without ``band_axis``.
    eps : float
        Norm product below which a spectrum is skipped.

    Returns
    -------
    float
        Mean spectral angle in degrees.

    References
    ----------
    F. A. Kruse et al., "The spectral image processing system (SIPS)", Remote Sensing of
    Environment 44, 1993.

    Examples
    --------
    >>> round(sam(np.array([1.0, 0.0]), np.array([1.0, 1.0]), band_axis=-1), 6)
    45.0
    """
    angles = _spectral_angles(estimate, truth, band_axis, mask, eps)
    if not angles.size:
        raise InvalidInputError("sam: no spectrum to evaluate (all masked or all zero)")
    return float(np.degrees(np.mean(angles)))


def _spectral_angles(estimate, truth, band_axis: int, mask=None, eps: float = 1e-12):
    """Angles (radians) of the spectra :func:`sam` averages (zero-norm spectra skipped)."""
    est, gt = _pair(estimate, truth)
    band_axis = _axis(band_axis, est)
    eps = _opt.number(eps, "eps")
    est = np.moveaxis(est, band_axis, -1)
    gt = np.moveaxis(gt, band_axis, -1)
    num = np.sum(est * gt, axis=-1)
    den = np.linalg.norm(est, axis=-1) * np.linalg.norm(gt, axis=-1)
    ok = den > eps
    if mask is not None:
        ok &= _opt.bool_mask(mask, "mask", ok.shape)
    return np.arccos(np.clip(num[ok] / den[ok], -1.0, 1.0))


def cube_scores(estimate, truth, data_range: float = 1.0) -> tuple[float, float]:
    """PSNR (dB) and mean spectral angle (degrees) of two plenoptic cubes, read one view at a
    time.

    The values :func:`psnr` and :func:`sam` (``band_axis=2``) give on the whole cubes (to
    rounding), without holding either: ``estimate`` and ``truth`` may be lazy h5py datasets
    (:func:`hyperlf.formats.open_gt_cube`, :func:`hyperlf.formats.open_cube_h5`).

    Parameters
    ----------
    estimate, truth : array_like, shape (R, C, B, H, W)
    data_range : float
        As :func:`psnr`.

    Returns
    -------
    psnr_db, sam_deg : float

    Examples
    --------
    >>> est = np.ones((1, 2, 3, 4, 5)); gt = est.copy(); gt[0, 1] *= 0.9
    >>> [round(v, 4) for v in cube_scores(est, gt)]
    [23.0103, 0.0]
    """
    data_range = _opt.number(data_range, "data_range", positive=True)
    if np.shape(estimate) != np.shape(truth) or len(np.shape(truth)) != 5:
        raise InvalidInputError(f"cube_scores needs two (R, C, B, H, W) cubes of one shape, got "
                                f"{np.shape(estimate)} and {np.shape(truth)}")
    R, C = np.shape(truth)[:2]
    sse = angle = 0.0
    n = m = 0
    for r in range(R):
        for c in range(C):
            est, gt = _pair(estimate[r, c], truth[r, c])
            sse += float(np.sum((est - gt) ** 2))
            n += est.size
            a = _spectral_angles(est, gt, 0)
            angle += float(a.sum())
            m += a.size
    if m == 0:
        raise InvalidInputError("cube_scores: no spectrum to evaluate (all zero)")
    return _psnr_of_mse(sse / n, data_range), float(np.degrees(angle / m))


def completion_ratio(valid) -> float:
    """Percentage of (view, band, pixel) entries marked valid in a completion mask.

    Parameters
    ----------
    valid : array_like of bool
        Completion mask, any shape.

    Returns
    -------
    float
        Valid entries, % of all entries.

    Examples
    --------
    >>> completion_ratio([True, False, True, True])
    75.0
    """
    v = np.asarray(valid, dtype=bool)
    if v.size == 0:
        raise InvalidInputError("completion_ratio: empty mask")
    return float(100.0 * v.mean())
