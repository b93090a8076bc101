"""Small per-image operations shared by the matching costs and the H-LF cues.

* :func:`normalise_intensity`: ``In = I / mean(I)`` (SPEC §3), the intensity normalisation of
  every cost and cue, so that views behind different filters (different exposure) compare.
* :func:`gradient_magnitude`: ``|grad In|`` with central differences and replicated borders.
* :func:`fill_masked`: every invalid pixel (validity mask, SPEC §11) takes the value of the
  nearest valid pixel, the masked analogue of the replicated border: window costs that reach
  into a region without data see its edge continued, not black.
* :func:`block_reduce`: ``factor x factor`` block means (or any reduction) over the last two
  axes, edges replicated: the coarse levels of the optimisers and of a light field.
* :func:`noise_sigma` and :func:`texture_snr`: how much texture a matching window holds above
  the sensor noise, which tells textureless regions (a white table, a wall) that no cost can
  match from the rest.
* :func:`edge_blur`: how soft the image's sharpest edges are (the Gaussian blur, px), which
  tells how far window costs carry a foreground over its blurred outline.
"""

from __future__ import annotations

import numpy as np

from . import _options as _opt
from .errors import InvalidInputError


def _grey(image, dtype=np.float64) -> np.ndarray:
    """``image`` as a 2-D array of ``dtype``."""
    a = _opt.real_array(image, "image", dtype)
    if a.ndim != 2:
        raise InvalidInputError(f"image must be a grey (H, W) array, got shape {a.shape}")
    return a


def normalise_intensity(image, dtype=np.float64, *, valid=None) -> np.ndarray:
    """Return ``image / mean(image)`` as ``dtype``.

    Parameters
    ----------
    image : array_like
        Linear intensities (any positive scale).
    dtype : numpy dtype, optional
        Working precision (float64).
    valid : array_like of bool, optional
        Validity mask of ``image`` (SPEC §11): the mean is taken over the valid pixels only,
        so that a region without data (black, or filled by :func:`fill_masked`) does not
        change the scale. Every pixel is divided by it. A mask with no valid pixel leaves the
        image's own mean (the view carries no data; every sample of it is invalid anyway).

    Returns
    -------
    ndarray
        The normalised image; its mean is 1.

    Raises
    ------
    InvalidInputError
        If the mean is not positive (not linear intensities).

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.imageops import normalise_intensity
    >>> normalise_intensity(np.array([[1.0, 3.0]])).tolist()
    [[0.5, 1.5]]
    """
    a = _opt.real_array(image, "image", _opt.float_dtype(dtype))
    if a.size == 0:
        raise InvalidInputError("image is empty: nothing to normalise")
    if valid is not None and np.any(
            valid := _opt.bool_mask(valid, "valid", a.shape, broadcast=True, of="the image")):
        m = float(a[valid].mean())
    elif valid is not None:
        m = float(a.mean()) if float(a.mean()) > 0 else 1.0
    else:
        m = float(a.mean())
    if not 0 < m < np.inf:
        raise InvalidInputError(
            f"image mean must be positive and finite to normalise I / mean(I), got {m!r} "
            "(linear intensities expected)")
    return a / m


def gradient_magnitude(image) -> np.ndarray:
    """Euclidean magnitude of the central-difference gradient ``(f[x+1] - f[x-1]) / 2``.

    Borders are replicated, so the result has the shape of ``image`` (2-D).

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.imageops import gradient_magnitude
    >>> gradient_magnitude(np.tile(np.arange(4.0), (3, 1)))[1].tolist()
    [0.5, 1.0, 1.0, 0.5]
    """
    gx, gy = _central_gradient(image)
    return np.sqrt(gx * gx + gy * gy)


def _central_gradient(image) -> tuple[np.ndarray, np.ndarray]:
    """``(d/dx, d/dy)`` by central differences, borders replicated."""
    a = np.asarray(image)
    if a.ndim != 2 or not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
        raise InvalidInputError(f"image must be a grey (H, W) array of numbers, got "
                                f"{_opt.shown(image)}")
    p = np.pad(a, 1, mode="edge")
    return (p[1:-1, 2:] - p[1:-1, :-2]) / 2.0, (p[2:, 1:-1] - p[:-2, 1:-1]) / 2.0


def fill_masked(image, valid) -> np.ndarray:
    """``image`` with every invalid pixel replaced by the value of the nearest valid pixel.

    The nearest pixel is the Euclidean one (ties as
    :func:`scipy.ndimage.distance_transform_edt` breaks them).  A mask with no valid pixel, or
    no invalid one, returns an unchanged copy.

    Parameters
    ----------
    image : array_like, shape (H, W)
    valid : array_like of bool, shape (H, W)
        True where the pixel holds real data.

    Returns
    -------
    ndarray, float64, shape (H, W)

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.imageops import fill_masked
    >>> fill_masked(np.array([[1.0, 0.0, 0.0, 4.0]]), np.array([[1, 0, 0, 1]], bool)).tolist()
    [[1.0, 1.0, 4.0, 4.0]]
    """
    from scipy.ndimage import distance_transform_edt

    a = np.array(_opt.real_array(image, "image"))
    v = _opt.bool_mask(valid, "valid", a.shape, of="the image")
    if v.all() or not v.any():
        return a
    idx = distance_transform_edt(~v, return_distances=False, return_indices=True)
    return a[tuple(idx)]


#: Immerkær's operator: the difference of two Laplacians, blind to planar and to most smooth
#: image structure; on white noise of std sigma its response has std ``6 sigma``.
_NOISE_KERNEL = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])


def noise_sigma(image, *, valid=None) -> float:
    """Standard deviation of the white noise of ``image``, estimated robustly.

    Immerkær's operator (a difference of Laplacians, blind to shading) is applied to the image
    and to its 2 x 2 binning; the median absolute response of each gives a standard deviation
    ``s = 1.4826 median |r| / 6`` (the median, unlike Immerkær's mean, lets edges, a minority
    of pixels, not count).  White noise halves under the binning and texture does not (the
    fine structure of natural and rendered scenes is about scale invariant), so
    ``sigma^2 = (s_1^2 - s_2^2) / (3 / 4)``: a rendered, noise-free light field, whose
    pixel-scale texture a single-scale estimate takes for noise, gets about 0.  Noise that
    depends on the signal (shot noise) is summarised by its typical level.

    Parameters
    ----------
    image : array_like, shape (H, W)
    valid : array_like of bool, shape (H, W), optional
        Pixels holding data; responses touching an invalid pixel are left out.

    Returns
    -------
    float
        0 for a noise-free image or one smaller than 6 x 6.

    References
    ----------
    .. [1] J. Immerkær, "Fast Noise Variance Estimation", Computer Vision and Image
       Understanding 64(2), 300-302, 1996.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.imageops import noise_sigma
    >>> img = 0.5 + 0.01 * np.random.default_rng(0).standard_normal((200, 200))
    >>> round(noise_sigma(img), 3)
    0.01
    """
    a = _grey(image)
    v = np.ones(a.shape, bool) if valid is None else _opt.bool_mask(valid, "valid", a.shape,
                                                                      of="the image")
    if min(a.shape) < 6:
        return 0.0
    H, W = (a.shape[0] // 2) * 2, (a.shape[1] // 2) * 2
    binned = a[:H, :W].reshape(H // 2, 2, W // 2, 2).mean(axis=(1, 3))
    v2 = v[:H, :W].reshape(H // 2, 2, W // 2, 2).all(axis=(1, 3))
    s1, s2 = _immerkaer_sigma(a, v), _immerkaer_sigma(binned, v2)
    return float(np.sqrt(max(s1 * s1 - s2 * s2, 0.0) / 0.75))


def _immerkaer_sigma(a: np.ndarray, valid: np.ndarray) -> float:
    """``1.4826 median |N * a| / 6`` over the responses that touch only valid pixels."""
    from scipy.ndimage import binary_erosion, convolve

    if min(a.shape) < 3:
        return 0.0
    use = np.zeros(a.shape, bool)
    use[1:-1, 1:-1] = True
    use &= binary_erosion(valid, np.ones((3, 3), bool))
    if not use.any():
        return 0.0
    r = np.abs(convolve(a, _NOISE_KERNEL, mode="reflect"))
    return float(1.4826 * np.median(r[use]) / 6.0)


def texture_snr(image, window: int = 5, *, sigma: float | None = None, valid=None) -> np.ndarray:
    """Texture-to-noise ratio of every ``window`` x ``window`` neighbourhood.

    Texture is what remains of the window after the best-fitting plane ``a + b x + c y`` is
    removed: window costs invariant to gain and offset (NCC, census) cannot match a plane
    (smooth shading, vignetting) any more than a constant.  With ``r^2`` the residual variance
    and ``n = window^2``, ``t = sqrt(max(r^2 n / ((n - 3) sigma^2) - 1, 0))``: the texture's
    standard deviation in units of the noise, about 0 where the window holds plane + noise.

    Parameters
    ----------
    image : array_like, shape (H, W)
    window : int
        Side of the (box) window, odd, >= 3: the matching window.
    sigma : float, optional
        The noise std; default :func:`noise_sigma` of ``image``.
    valid : array_like of bool, optional
        Passed to :func:`noise_sigma` when ``sigma`` is estimated.

    Returns
    -------
    ndarray, float64, shape (H, W)
        ``inf`` everywhere when the noise is 0.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.imageops import texture_snr
    >>> rng = np.random.default_rng(0)
    >>> yy, xx = np.mgrid[0:64, 0:128]
    >>> img = 0.2 + 0.004 * xx + 0.003 * yy + 0.01 * rng.standard_normal((64, 128))  # shading
    >>> img[:, 64:] += 0.05 * rng.standard_normal((64, 64))  # texture on the right
    >>> t = texture_snr(img, 5, sigma=0.01)
    >>> bool(np.median(t[:, :60]) < 0.5), bool(np.median(t[:, 70:]) > 3)
    (True, True)
    """
    from scipy.ndimage import correlate, uniform_filter

    a = _grey(image)
    w = _opt.window(_opt.integer(window, "window", 3, odd=True), "window", side=max(a.shape))
    s = noise_sigma(a, valid=valid) if sigma is None else _opt.number(sigma, "sigma")
    if not s * s > 0:  # no noise (or a sigma whose square is 0 in float64)
        return np.full(a.shape, np.inf)
    n = w * w
    m = uniform_filter(a, w, mode="reflect")
    var = uniform_filter(a * a, w, mode="reflect") - m * m
    ramp = np.tile(np.arange(w, dtype=np.float64) - w // 2, (w, 1))  # x in the window
    var_ramp = float((ramp * ramp).mean())
    for kernel in (ramp, ramp.T):  # the plane's x and y terms take their variance
        cov = correlate(a, kernel / n, mode="reflect")
        var = var - cov * cov / var_ramp
    ratio = np.maximum(var, 0.0) * n / ((n - 3) * s * s)
    return np.sqrt(np.maximum(ratio - 1.0, 0.0))


#: The largest re-blur (px) :func:`edge_blur` takes: far beyond any edge it can measure.
MAX_REBLUR = 50.0


def edge_blur(image, *, valid=None, reblur: float = 1.0, share: float = 0.1,
              min_edges: int = 100) -> float:
    """Gaussian blur (px) of the image's sharpest edges, from how much a known blur softens them.

    A step edge blurred by a Gaussian of ``s`` px has a gradient maximum proportional to
    ``1 / s``; blurred again by ``reblur`` px, to ``1 / sqrt(s^2 + reblur^2)``. So the ratio
    ``r`` of the two gradient magnitudes at the edge gives ``s = reblur / sqrt(r^2 - 1)``,
    whatever the edge's contrast [1]_. The edges are the pixels whose gradient magnitude
    (:func:`gradient_magnitude`) is a maximum across the edge (non-maximum suppression, four
    directions) and among the strongest ``share`` of the image's; the result is the median over
    them. A sharp step reads 0.6-0.85 px (the differences' own width; a rendered light field
    reads so too).

    Parameters
    ----------
    image : array_like, shape (H, W)
    valid : array_like of bool, shape (H, W), optional
        Pixels with data: the rest is filled (:func:`fill_masked`) and no edge within
        ``3 reblur + 1`` px of it is counted.
    reblur : float
        The known blur, px.
    share : float
        Fraction of the (valid) pixels, by gradient magnitude, that may count as edges.
    min_edges : int
        Fewer edge pixels than this: NaN (no edge to tell).

    Returns
    -------
    float
        Blur in px (NaN when the image has too few edges).

    References
    ----------
    .. [1] S. Zhuo and T. Sim, "Defocus map estimation from a single image", Pattern
       Recognition 44(9), 2011.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.ndimage import gaussian_filter
    >>> from hyperlf.imageops import edge_blur
    >>> steps = np.kron(np.random.default_rng(0).random((16, 16)), np.ones((16, 16)))
    >>> round(edge_blur(gaussian_filter(steps, 2.0)), 1)
    2.1
    """
    from scipy.ndimage import binary_erosion, gaussian_filter

    reblur = _opt.number(reblur, "edge_blur's reblur", positive=True, at_most=MAX_REBLUR)
    if not _opt.share(share, "edge_blur's share") > 0:
        raise InvalidInputError("edge_blur's share must be in (0, 1], got 0")
    min_edges = _opt.integer(min_edges, "edge_blur's min_edges", 1)
    a = _grey(image)
    keep = np.ones(a.shape, bool)
    if valid is not None:
        v = _opt.bool_mask(valid, "valid", a.shape, of="the image")
        a = fill_masked(a, v)
        keep = binary_erosion(v, iterations=int(3 * reblur) + 1, border_value=1)
        if not keep.any():
            return float("nan")
    gx, gy = _central_gradient(a)
    m = np.sqrt(gx * gx + gy * gy)
    edges = keep & _ridge(m, gx, gy) & (m > np.quantile(m[keep], 1.0 - share))
    ratio = m[edges] / np.maximum(gradient_magnitude(gaussian_filter(a, reblur))[edges], 1e-300)
    ratio = ratio[ratio > 1.0 + 1e-9]
    if ratio.size < min_edges:
        return float("nan")
    return float(np.median(reblur / np.sqrt(ratio * ratio - 1.0)))


def _ridge(m: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """Pixels where ``m`` is at least its two neighbours along the gradient (quantised to
    0, 45, 90, 135 degrees)."""
    H, W = m.shape
    p = np.pad(m, 1, mode="edge")
    direction = np.round(np.arctan2(gy, gx) / (np.pi / 4)).astype(np.int64) % 4
    out = np.zeros(m.shape, bool)
    for k, (dy, dx) in enumerate(((0, 1), (1, 1), (1, 0), (1, -1))):
        ahead = p[1 + dy:1 + dy + H, 1 + dx:1 + dx + W]
        behind = p[1 - dy:1 - dy + H, 1 - dx:1 - dx + W]
        out |= (direction == k) & (m >= ahead) & (m >= behind)
    return out


def block_reduce(a, factor: int = 2, how=np.mean) -> np.ndarray:
    """``how`` over the ``factor x factor`` blocks of the last two axes of ``a``.

    Sizes are rounded up: the last row and column are repeated to a multiple of ``factor``.

    Parameters
    ----------
    a : ndarray, (..., H, W)
    factor : int
        Block side (>= 1).
    how : callable
        A numpy reduction taking ``axis=`` (``np.mean``, ``np.all``, ``np.min``, ...).

    Returns
    -------
    ndarray, (..., ceil(H / factor), ceil(W / factor))

    Examples
    --------
    >>> block_reduce(np.arange(6.0).reshape(2, 3)).tolist()
    [[2.0, 3.5]]
    """
    a = np.asarray(a)
    if a.ndim < 2 or not callable(how):
        raise InvalidInputError(f"block_reduce needs an (..., H, W) array and a callable how, "
                                f"got shape {a.shape} and {_opt.shown(how)}")
    H, W = a.shape[-2:]
    # a larger factor only repeats the edges into a 1 x 1 block, at (H + f)(W + f) memory
    factor = _opt.integer(factor, "factor", 1, maximum=4 * max(H, W) + 4)
    ph, pw = -H % factor, -W % factor
    if ph or pw:
        a = np.pad(a, [(0, 0)] * (a.ndim - 2) + [(0, ph), (0, pw)], mode="edge")
    h, w = a.shape[-2] // factor, a.shape[-1] // factor
    return how(a.reshape(a.shape[:-2] + (h, factor, w, factor)), axis=(-3, -1))
