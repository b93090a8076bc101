"""Spectral-invariant descriptor (SPEC §2, paper §4.1) in its two variants (SPEC §3).

For one view ``I`` the descriptor is a stack of ``n_channels`` maps (612 with the defaults):

1. ``In = I / mean(I)`` (:func:`normalise`), optionally pre-smoothed by a Gaussian of
   ``presmooth_sigma`` (default 0 = off; borders replicated).
2. Gradients of ``In`` (:func:`gradients`), borders replicated (``mode='nearest'``):

   * ``"central"`` (literal, variant ``paper``): ``gx = (In[y, x+1] - In[y, x-1]) / 2``,
     ``gy = (In[y+1, x] - In[y-1, x]) / 2`` (``y`` grows downwards);
   * ``"sobel"`` (variant ``default``): Sobel / 4 = ``scipy.ndimage.sobel(In, axis,
     mode='nearest') / 4``, i.e. ``gx = sum_dy w_dy (In[y+dy, x+1] - In[y+dy, x-1]) / 4`` with
     ``w = (1, 2, 1)`` (as measured in the prototype).  Note there is no ``/2`` on the
     difference: on a ramp of slope 1 it gives 2, twice the ``"central"`` value, which is part
     of why it shifts mass to ``h3``.

   ``M = sqrt(gx^2 + gy^2)``; ``Theta = (atan2(gy, gx) mod pi) / pi`` in ``[0, 1)``.  The
   ``mod pi`` is computed by first flipping ``(gx, gy)`` into the upper half plane
   (``gy > 0``, or ``gy == 0`` and ``gx >= 0``; negative zeros cleared), so that ``Theta`` is
   *bit-exactly* the same for ``(gx, gy)`` and ``(-gx, -gy)``; a result that rounds to 1 is
   mapped to 0.  ``atan2(0, 0)`` gives 0 (so flat pixels land in direction bin 0, as measured
   in the prototype notes F3).
3. Overlapping bins (:func:`bin_weights`): bin width ``s``, overlap ``o`` (a fraction of ``s``),
   bin ``k`` covers ``[k (1-o) s, k (1-o) s + s)``, ``K`` bins.  A value falls in one or two
   bins (``o < 1/2`` is required so that it is never three).  **A value in two bins is counted
   fully (weight 1) in each**; the histogram normalisation by its own sum then takes care of
   the total.  Values at or past the end of the last bin are counted in the last bin only.
   (Negative values, which ``M`` and ``Theta`` never take, would go to bin 0.)
4. For each window width ``w`` (default ``(3, 5, 9)``) and pixel ``p``, with Gaussian spatial
   weights ``G(p, u) = exp(-|p - u|^2 / (2 sigma_g^2))``, ``sigma_g = sigma_g_factor * w``
   (default ``w / 2``), over the ``w x w`` window:

   * ``h1[k] = sum_u G(p, u) [M(u) in bin k]``,
   * ``h2[k] = sum_u G(p, u) [Theta(u) in bin k]``,
   * ``h3[k] = sum_u G(p, u) M(u) [Theta(u) in bin k]`` (O-HOG),

   each divided by its own sum over ``k`` (an all-zero histogram stays zero).  **Window pixels
   outside the image take the value of the nearest border pixel (replicate border)**, so every
   window has the full Gaussian mass; a histogram over a window is a separable Gaussian-weighted
   filter of per-bin indicator maps with ``BORDER_REPLICATE``.
5. Edge weights at ``p``: ``a1 = a2 = beta exp(-M(p)^2 / sigma_w)``, ``a3 = 1 - a1 - a2``.
   Variant ``paper``: ``beta = 1/2``, ``sigma_w = 0.16``.  Variant ``default``: ``sigma_w =
   "auto"`` = ``median(M^2) / ln 2`` over the image (computed per view, so the median pixel
   gets ``a3 = 1/2``); with ``beta = 1/2`` this is exactly the measured ``a3 = 1 - exp(-M^2 /
   sigma_w)``, ``a1 = a2 = (1 - a3) / 2`` of SPEC §3.  If ``median(M^2)`` is 0 (more than half
   the pixels flat) the median of the non-zero ``M^2`` is used; if ``M`` is 0 everywhere,
   ``a1 = a2 = beta`` and ``a3 = 1 - 2 beta``.
6. ``D_p(w) = [a1 h1, a2 h2, a3 h3]`` (``3K`` channels) and ``H_p = [D_p(w_1), D_p(w_2), ...]``.

Channel order: level-major, ``channel = level * 3K + hist * K + bin`` with ``hist`` 0, 1, 2 for
``h1, h2, h3`` (see :attr:`DescriptorParams.channel_levels`, ``channel_hist``, ``channel_bin``).

Sums.  ``h1`` and ``h2`` are never empty (every pixel falls in a bin and ``G > 0``), and ``h3``
is empty only when ``M == 0`` on the whole window, which implies ``M(p) = 0`` and hence
``a3 = 1 - 2 beta``.  So each ``D_p(w)`` sums to 1 (and ``H_p`` to the number of levels, 3)
whenever ``beta = 1/2`` (both variants); with ``beta < 1/2`` a window where ``M`` is 0
everywhere sums to ``2 beta`` (documented degenerate case).  In float32 the sums hold to ~1e-6.

Invariances (exact in real arithmetic; see the tests):

* a global gain ``I -> g I`` leaves ``In`` and hence the whole descriptor unchanged;
* ``(gx, gy) -> (-gx, -gy)`` leaves ``M`` and ``Theta`` (mod pi) unchanged, hence everything;
* a contrast reversal ``I -> c - I`` (``c > mean(I)``) gives ``In' = -k In + const`` with
  ``k = mean(I) / (c - mean(I))``, so gradients scale by ``-k``: ``Theta`` and therefore ``h2``
  and the normalised ``h3`` are unchanged, while ``M`` scales by ``k`` so ``h1`` changes unless
  ``k = 1`` (``c = 2 mean(I)``, where ``In' = 2 - In`` and the whole descriptor is unchanged).
  With ``sigma_w = "auto"`` the weights ``a1, a2, a3`` are invariant too (``sigma_w`` scales by
  ``k^2``); with a fixed ``sigma_w`` (variant ``paper``) they are not.

Implementations (``impl``): ``"numpy"`` = :func:`descriptor_reference` (per-bin indicator maps
filtered with ``scipy.ndimage.correlate1d(mode='nearest')``, float64); ``"numba"`` = a parallel
sparse-gather kernel (each window pixel votes into at most two bins), float64 accumulation;
``"auto"`` = ``"numba"``.  The per-pixel preparation (normalisation, gradients, bins, weights)
is shared numpy code; both accumulate in float64 and return float32; they agree to float32
rounding (bit-identical on the test images and on Middlebury Tsukuba/Teddy).

Memory.  The full descriptor is ``n_channels * H * W`` float32 (413 MB at 450 x 375, 2.6 GB at
1200 x 900).  :func:`prepare` computes the per-view inputs once (a few ``H x W`` maps);
``descriptor(prepared, channels=...)`` and :func:`iter_descriptor_blocks` then compute only the
requested channels, so a caller can stream blocks of channels and hold one block at a time.

References
----------
.. [1] K. Zhu, Y. Xue, Q. Fu, S. B. Kang, X. Chen, J. Yu, "Hyperspectral Light Field Stereo
   Matching" (§4.1: the spectral-invariant descriptor and BWNCC).

Examples
--------
>>> import numpy as np
>>> from hyperlf.descriptor import DescriptorParams, descriptor
>>> img = np.random.default_rng(0).random((24, 32)) + 0.5
>>> D = descriptor(img)                        # all 612 channels, float32
>>> D.shape, DescriptorParams().n_channels
((612, 24, 32), 612)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterator, Union

import numpy as np
from scipy import ndimage

from ._options import (array, check_fields, choice, flag, integer, number, params_of, rule,
                       shown, word_or)
from .errors import InvalidInputError

__all__ = [
    "DescriptorParams",
    "PreparedDescriptor",
    "normalise",
    "gradients",
    "bin_weights",
    "auto_sigma_w",
    "edge_weights",
    "prepare",
    "descriptor",
    "descriptor_reference",
    "iter_descriptor_blocks",
    "magnitude_direction",
    "prepare_from_gradients",
]

_GRADIENTS = ("central", "sobel")
_IMPLS = ("auto", "numpy", "numba")


# --------------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------------


def _odd_windows(value, label) -> tuple:
    """One odd window width or several, as a tuple of ints."""
    items = value.ravel().tolist() if isinstance(value, np.ndarray) else (
        list(value) if isinstance(value, (tuple, list)) else [value])
    try:
        if not items:
            raise InvalidInputError("no window")
        return tuple(integer(w, label, 1, odd=True) for w in items)
    except InvalidInputError:
        raise InvalidInputError(f"{label} must be odd integers >= 1, got {shown(value)}") from None


@dataclass(frozen=True)
class DescriptorParams:
    """All constants of the descriptor (SPEC §2, §3).

    The class defaults are the measured-better ``default`` variant (``bwncc`` of SPEC §3);
    :meth:`paper` gives the literal paper/SPEC §2 values.

    Attributes
    ----------
    bin_width : float
        ``s``, default 1/64.
    overlap : float
        ``o``, a fraction of ``bin_width`` in ``[0, 1/2)``; neighbouring bins share ``o * s``.
    n_bins : int
        ``K`` bins per histogram, default 68.
    windows : tuple of int
        Odd window widths ``w`` of the pyramid levels, default ``(3, 5, 9)``.
    sigma_g_factor : float
        ``sigma_g = sigma_g_factor * w``, default 1/2.
    beta : float
        ``a1 = a2 = beta exp(-M^2 / sigma_w)``, in ``[0, 1/2]``, default 1/2.
    sigma_w : float or "auto"
        Positive float, or ``"auto"`` = ``median(M^2) / ln 2`` per image.
    gradient : "central" or "sobel"
        Central differences / 2, or Sobel / 4 (borders replicated).
    presmooth_sigma : float
        Gaussian pre-smoothing of ``In`` before the gradient (0 = off).
    """

    bin_width: float = 1.0 / 64.0
    overlap: float = 1.0 / 16.0
    n_bins: int = 68
    windows: tuple = (3, 5, 9)
    sigma_g_factor: float = 0.5
    beta: float = 0.5
    sigma_w: Union[float, str] = "auto"
    gradient: str = "sobel"
    presmooth_sigma: float = 0.0

    def __post_init__(self):
        check_fields(self, {
            "windows": _odd_windows, "bin_width": rule(number, positive=True),
            "overlap": rule(number, below=0.5), "n_bins": rule(integer, minimum=1),
            "sigma_g_factor": rule(number, positive=True), "beta": rule(number, at_most=0.5),
            "sigma_w": word_or(rule(number, positive=True), ("auto",),
                               "'auto' or a finite number > 0"),
            "gradient": rule(choice, choices=_GRADIENTS), "presmooth_sigma": number})

    # -- variants ------------------------------------------------------------------------
    @classmethod
    def default(cls, **overrides) -> "DescriptorParams":
        """The measured-better ``bwncc`` variant (SPEC §3): Sobel/4, ``sigma_w = "auto"``."""
        return cls(**overrides)

    @classmethod
    def paper(cls, **overrides) -> "DescriptorParams":
        """The literal paper / SPEC §2 variant: central differences, ``sigma_w = 0.16``."""
        kw = dict(gradient="central", sigma_w=0.16)
        kw.update(overrides)
        return cls(**kw)

    # -- derived quantities --------------------------------------------------------------
    @property
    def bin_step(self) -> float:
        """Distance between consecutive bin starts, ``(1 - o) s``."""
        return (1.0 - self.overlap) * self.bin_width

    @property
    def bin_starts(self) -> np.ndarray:
        return np.arange(self.n_bins) * self.bin_step

    @property
    def n_levels(self) -> int:
        return len(self.windows)

    @property
    def channels_per_level(self) -> int:
        return 3 * self.n_bins

    @property
    def n_channels(self) -> int:
        return self.n_levels * self.channels_per_level

    @property
    def channel_levels(self) -> np.ndarray:
        """Window width ``w`` of each channel, shape ``(n_channels,)``."""
        return np.repeat(np.asarray(self.windows, dtype=np.int64), self.channels_per_level)

    @property
    def channel_level_index(self) -> np.ndarray:
        """Pyramid level (0, 1, ...) of each channel."""
        return np.arange(self.n_channels) // self.channels_per_level

    @property
    def channel_hist(self) -> np.ndarray:
        """Histogram of each channel: 0 = h1 (magnitude), 1 = h2 (direction), 2 = h3 (O-HOG)."""
        return (np.arange(self.n_channels) % self.channels_per_level) // self.n_bins

    @property
    def channel_bin(self) -> np.ndarray:
        """Bin index ``k`` of each channel."""
        return np.arange(self.n_channels) % self.n_bins

    def sigma_g(self, w: int) -> float:
        return self.sigma_g_factor * w


# --------------------------------------------------------------------------------------------
# Per-pixel preparation (shared by all implementations)
# --------------------------------------------------------------------------------------------


def _as_image(image) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim != 2:
        raise InvalidInputError(f"image must be 2-D (H, W), got shape {img.shape}")
    if img.size == 0:
        raise InvalidInputError("image is empty")
    if not np.issubdtype(img.dtype, np.number) or np.iscomplexobj(img):
        raise InvalidInputError(f"image must be real-valued, got dtype {img.dtype}")
    img = img.astype(np.float64, copy=False)
    if not np.all(np.isfinite(img)):
        raise InvalidInputError("image contains NaN or infinite values; fill or mask them first")
    return img


#: Largest gradient value :func:`magnitude_direction` and the magnitude helpers take: its
#: square (``M^2``) must stay finite in float64 (a normalised image's gradients are far below).
_MAX_GRADIENT = 1e150


def _real_values(value, label: str, *, two_d: bool = False, at_least: float | None = None
                 ) -> np.ndarray:
    """``value`` as a non-empty float64 array (2-D where ``two_d``) of finite values of size at
    most :data:`_MAX_GRADIENT` (``>= at_least`` where given): the public helpers' one check
    (:func:`hyperlf._options.array`; the descriptor's own pipeline calls their unchecked
    cores)."""
    a = array(value, label, ndim=2 if two_d else None, empty=False, bound=_MAX_GRADIENT,
              of=" (H, W)" if two_d else "")
    a = np.asarray(a, dtype=np.float64)
    if at_least is not None and not bool(np.all(a >= at_least)):
        raise InvalidInputError(f"{label} must be >= {at_least:g} everywhere, got a minimum of "
                                f"{a.min():g}")
    return a


def _gradient_pair(gx, gy, *, two_d: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``gx`` and ``gy`` checked by :func:`_real_values`, of one shape."""
    gx, gy = _real_values(gx, "gx", two_d=two_d), _real_values(gy, "gy", two_d=two_d)
    if gx.shape != gy.shape:
        raise InvalidInputError(f"gx and gy must have the same shape, got {gx.shape} and "
                                f"{gy.shape}")
    return gx, gy


def normalise(image) -> np.ndarray:
    """``In = I / mean(I)`` in float64 (SPEC §2 step 1). The mean must be positive.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.descriptor import normalise
    >>> In = normalise([[1, 2], [3, 6]])            # divided by the mean, 3
    >>> In.tolist(), In.dtype.name
    ([[0.333..., 0.666...], [1.0, 2.0]], 'float64')
    >>> img = np.random.default_rng(0).random((8, 10)) + 0.5
    >>> bool(np.allclose(normalise(img), normalise(7.0 * img)))    # a global gain cancels
    True
    """
    img = _as_image(image)
    m = float(np.mean(img))
    if not m > 0:
        raise InvalidInputError(f"image mean must be > 0 to normalise by it, got {m!r}")
    return img / m


def gradients(In, method: str = "sobel"):
    """Gradients of ``In`` with replicated borders: ``(gx, gy, M, Theta)``, float64.

    ``method="central"``: ``(f[x+1] - f[x-1]) / 2``; ``method="sobel"``: Sobel / 4.  ``gx``
    is along columns (x), ``gy`` along rows (y, growing downwards).  ``M = hypot``-free
    ``sqrt(gx^2 + gy^2)``; ``Theta = (atan2(gy, gx) mod pi) / pi`` in ``[0, 1)``, bit-exactly
    invariant under ``(gx, gy) -> (-gx, -gy)`` (see the module docstring).  ``In``: a finite
    2-D image (values at most 1e150 in size).

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.descriptor import gradients
    >>> ramp = 1.0 + 0.1 * np.arange(10) * np.ones((8, 1))     # slope 0.1 along x
    >>> gx, gy, M, Theta = gradients(ramp, "central")
    >>> bool(np.allclose(gx[:, 1:-1], 0.1)), bool(np.all(gy == 0)), bool(np.all(Theta == 0))
    (True, True, True)
    >>> round(float(gx[0, 0]), 6)       # the first column is repeated past the border
    0.05
    >>> gx, gy, M, Theta = gradients(ramp.T)                    # "sobel", slope 0.1 along y
    >>> bool(np.allclose(gy[1:-1], 0.2)), bool(np.allclose(Theta, 0.5))   # Sobel: 2 x slope
    (True, True)
    """
    choice(method, "gradient method", _GRADIENTS)
    return _gradients(_real_values(In, "In", two_d=True), method)


def _gradients(In: np.ndarray, method: str):
    """:func:`gradients` of a checked float64 image."""
    if method == "central":
        p = np.pad(In, 1, mode="edge")
        gx = (p[1:-1, 2:] - p[1:-1, :-2]) / 2.0
        gy = (p[2:, 1:-1] - p[:-2, 1:-1]) / 2.0
    elif method == "sobel":
        gx = ndimage.sobel(In, axis=1, mode="nearest") / 4.0
        gy = ndimage.sobel(In, axis=0, mode="nearest") / 4.0
    M, Theta = _magnitude_direction(gx, gy)
    return gx, gy, M, Theta


def magnitude_direction(gx, gy):
    """``M = sqrt(gx^2 + gy^2)`` and ``Theta = (atan2(gy, gx) mod pi) / pi`` in ``[0, 1)``.

    ``gx`` and ``gy``: arrays of one shape, finite, at most 1e150 in size (so that ``M^2`` is).

    Examples
    --------
    >>> from hyperlf.descriptor import magnitude_direction
    >>> M, Theta = magnitude_direction([3.0, 0.0, 1.0, -1.0], [4.0, 1.0, 1.0, -1.0])
    >>> M.round(6).tolist()
    [5.0, 1.0, 1.414214, 1.414214]
    >>> Theta.round(4).tolist()     # (1, 1) and (-1, -1) share a direction (mod pi)
    [0.2952, 0.5, 0.25, 0.25]
    """
    return _magnitude_direction(*_gradient_pair(gx, gy))


def _magnitude_direction(gx, gy):
    """:func:`magnitude_direction` of checked gradients."""
    gx = np.asarray(gx, dtype=np.float64) + 0.0  # + 0.0 turns -0.0 into +0.0
    gy = np.asarray(gy, dtype=np.float64) + 0.0
    M = np.sqrt(gx * gx + gy * gy)
    flip = (gy < 0) | ((gy == 0) & (gx < 0))
    ux = np.where(flip, -gx, gx)
    uy = np.where(flip, -gy, gy)
    theta = np.arctan2(uy, ux) / np.pi  # in [0, 1]
    theta = np.where(theta >= 1.0, 0.0, theta) + 0.0
    return M, theta


def bin_weights(values, params: DescriptorParams | None = None):
    """Overlapping-bin membership of ``values``: ``(idx0, w0, idx1, w1)``.

    ``idx0`` (int32) is the lowest bin containing the value and ``idx1`` the next bin
    (``idx0 + 1``) when the value lies in the overlap of the two, else -1.  Each bin a value
    falls in counts it fully: ``w0 = 1`` everywhere, ``w1 = 1`` where ``idx1 >= 0`` else 0
    (float64).  Bin ``k`` covers ``[k (1-o) s, k (1-o) s + s)``; values at or past the end of
    the last bin go to the last bin only; negative values go to bin 0.  ``values`` must be
    finite.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.descriptor import DescriptorParams, bin_weights
    >>> p = DescriptorParams(bin_width=1.0, overlap=0.25, n_bins=4)
    >>> p.bin_starts.tolist()                   # bin k covers [start, start + 1)
    [0.0, 0.75, 1.5, 2.25]
    >>> idx0, w0, idx1, w1 = bin_weights([0.5, 0.8, 1.6, 10.0, -1.0], p)
    >>> idx0.tolist(), idx1.tolist()            # 0.8 lies in [0, 1) and in [0.75, 1.75)
    ([0, 0, 1, 3, 0], [-1, 1, 2, -1, -1])
    >>> w0.tolist(), w1.tolist()                # a value counts fully in each bin it falls in
    ([1.0, 1.0, 1.0, 1.0, 1.0], [0.0, 1.0, 1.0, 0.0, 0.0])
    """
    return _bin_weights(_real_values(values, "values"),
                        params_of(params, "params", DescriptorParams))


def _bin_weights(values, params: DescriptorParams):
    """:func:`bin_weights` of checked values."""
    v = np.asarray(values, dtype=np.float64)
    step = params.bin_step
    s = params.bin_width
    K = params.n_bins
    with np.errstate(invalid="ignore"):
        k = np.floor(v / step)
        # correct rounding of the division so that k * step <= v < (k + 1) * step exactly
        k = np.where(k * step > v, k - 1, k)
        k = np.where((k + 1) * step <= v, k + 1, k)
    k = np.clip(k, 0, K - 1).astype(np.int64)  # largest bin whose start is <= v
    # the previous bin also contains v when v < (k - 1) step + s
    two = (k >= 1) & (v < (k - 1) * step + s)
    idx0 = np.where(two, k - 1, k).astype(np.int32)
    idx1 = np.where(two, k, -1).astype(np.int32)
    w0 = np.ones(v.shape, dtype=np.float64)
    w1 = two.astype(np.float64)
    return idx0, w0, idx1, w1


def auto_sigma_w(M) -> float:
    """``median(M^2) / ln 2`` (0 only if ``M`` is 0 everywhere; see the module docstring).

    ``M``: gradient magnitudes, finite, ``>= 0`` and at most 1e150.

    Examples
    --------
    >>> import math
    >>> from hyperlf.descriptor import auto_sigma_w
    >>> bool(math.isclose(auto_sigma_w([0.0, 1.0, 2.0]), 1 / math.log(2)))   # median(M^2) = 1
    True
    >>> bool(math.isclose(auto_sigma_w([0.0, 0.0, 0.0, 2.0]), 4 / math.log(2)))   # non-zero M^2
    True
    >>> auto_sigma_w([0.0, 0.0])
    0.0
    """
    return _auto_sigma_w(_real_values(M, "M", at_least=0.0))


def _auto_sigma_w(M) -> float:
    """:func:`auto_sigma_w` of checked magnitudes."""
    m2 = np.asarray(M, dtype=np.float64) ** 2
    med = float(np.median(m2))
    if med <= 0:
        nz = m2[m2 > 0]
        med = float(np.median(nz)) if nz.size else 0.0
    return med / math.log(2.0)


def edge_weights(M, params: DescriptorParams | None = None, sigma_w: float | None = None):
    """``(a1, a3, sigma_w)`` with ``a1 = a2 = beta exp(-M^2 / sigma_w)``, ``a3 = 1 - 2 a1``.

    ``M``: gradient magnitudes as :func:`auto_sigma_w` takes them; ``sigma_w``: a finite number
    ``>= 0`` (0: ``M`` is taken as 0 everywhere), default from ``params``.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.descriptor import DescriptorParams, edge_weights
    >>> a1, a3, sigma_w = edge_weights([0.0, 1.0, 2.0])         # sigma_w "auto" = 1 / ln 2
    >>> a1.round(6).tolist(), a3.round(6).tolist()              # the median pixel gets a3 = 1/2
    ([0.5, 0.25, 0.03125], [0.0, 0.5, 0.9375])
    >>> bool(np.allclose(2 * a1 + a3, 1.0))                     # a1 + a2 + a3 = 1
    True
    >>> a1, a3, sigma_w = edge_weights([0.4], DescriptorParams.paper())   # fixed sigma_w = 0.16
    >>> sigma_w, round(float(a1[0]), 6)                         # 0.5 * exp(-0.16 / 0.16)
    (0.16, 0.18394)
    """
    return _edge_weights(_real_values(M, "M", at_least=0.0),
                         params_of(params, "params", DescriptorParams),
                         number(sigma_w, "sigma_w", optional=True))


def _edge_weights(M, params: DescriptorParams, sigma_w: float | None = None):
    """:func:`edge_weights` of checked values."""
    M = np.asarray(M, dtype=np.float64)
    if sigma_w is None:
        sigma_w = _auto_sigma_w(M) if params.sigma_w == "auto" else float(params.sigma_w)
    if sigma_w > 0:
        with np.errstate(over="ignore"):  # a tiny sigma_w: the weight's limit, 0
            a1 = params.beta * np.exp(-(M * M) / sigma_w)
    else:  # M == 0 everywhere
        a1 = np.full(M.shape, params.beta)
    a3 = 1.0 - a1 - a1
    return a1, a3, float(sigma_w)


def _gaussian_window(w: int, sigma_g: float) -> np.ndarray:
    """1-D factor of the separable window weights ``exp(-d^2 / (2 sigma_g^2))``, d = -r..r."""
    r = w // 2
    d = np.arange(-r, r + 1, dtype=np.float64)
    return np.exp(-(d * d) / (2.0 * sigma_g * sigma_g))


@dataclass(frozen=True, eq=False)
class PreparedDescriptor:
    """Per-view inputs of the descriptor, computed once by :func:`prepare` (a few H x W maps).

    Pass it to :func:`descriptor` / :func:`iter_descriptor_blocks` instead of the image to
    compute channels block by block without recomputing gradients and bins.
    """

    params: DescriptorParams
    In: np.ndarray
    gx: np.ndarray
    gy: np.ndarray
    M: np.ndarray
    Theta: np.ndarray
    m_idx0: np.ndarray
    m_idx1: np.ndarray
    t_idx0: np.ndarray
    t_idx1: np.ndarray
    a1: np.ndarray
    a3: np.ndarray
    sigma_w: float
    cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        # O(1): types and shapes only (one per view, built by :func:`prepare`)
        params_of(self.params, "params", DescriptorParams)
        shape = None
        for name in ("In", "gx", "gy", "M", "Theta", "m_idx0", "m_idx1", "t_idx0", "t_idx1",
                     "a1", "a3"):
            a = getattr(self, name)
            kind = "iu" if "idx" in name else "f"
            if not isinstance(a, np.ndarray) or a.dtype.kind not in kind or a.ndim != 2 or (
                    shape is not None and a.shape != shape):
                what = "integer" if "idx" in name else "float"
                raise InvalidInputError(
                    f"PreparedDescriptor.{name} must be a 2-D {what} array of the shape of In "
                    f"(build one with hyperlf.descriptor.prepare), got {shown(a)}")
            shape = a.shape
        object.__setattr__(self, "sigma_w", number(self.sigma_w, "PreparedDescriptor.sigma_w"))
        if not isinstance(self.cache, dict):
            raise InvalidInputError(f"PreparedDescriptor.cache must be a dict, got "
                                    f"{type(self.cache).__name__}")

    @property
    def shape(self):
        return self.In.shape


def prepare(image, params: DescriptorParams | None = None) -> PreparedDescriptor:
    """Normalise, differentiate and bin one view (everything but the window histograms).

    Parameters
    ----------
    image : (H, W) array or PreparedDescriptor
        A view (linear intensity, positive mean); a PreparedDescriptor is returned as is.
    params : DescriptorParams, optional
        Default ``DescriptorParams.default()``.

    Returns
    -------
    PreparedDescriptor
        The per-view inputs that :func:`descriptor` and :func:`iter_descriptor_blocks` reuse.

    Raises
    ------
    InvalidInputError
        Not a finite 2-D image with a positive mean, or a prepared view with other params.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.descriptor import descriptor, gradients, normalise, prepare
    >>> img = np.random.default_rng(1).random((16, 20)) + 0.5
    >>> prep = prepare(img)
    >>> prep.shape, bool(np.array_equal(prep.M, gradients(normalise(img))[2]))
    ((16, 20), True)
    >>> D = descriptor(prep, channels=[0, 300, 611])        # only three channels computed
    >>> D.shape, bool(np.allclose(D, descriptor(img)[[0, 300, 611]]))
    ((3, 16, 20), True)
    >>> prepare(prep) is prep
    True
    """
    if isinstance(image, PreparedDescriptor):
        if params is not None and params_of(params, "params", DescriptorParams) != image.params:
            raise InvalidInputError("prepared descriptor was built with different params")
        return image
    params = DescriptorParams() if params is None else params
    if not isinstance(params, DescriptorParams):
        raise InvalidInputError(f"params must be a DescriptorParams, got {type(params).__name__}")
    In = normalise(image)
    if params.presmooth_sigma > 0:
        In = ndimage.gaussian_filter(In, params.presmooth_sigma, mode="nearest")
    gx, gy, M, Theta = _gradients(In, params.gradient)
    return _prepare_from(params, In, gx, gy, M, Theta)


def prepare_from_gradients(gx, gy, params: DescriptorParams | None = None) -> PreparedDescriptor:
    """Like :func:`prepare` but from given gradients (for tests and custom gradient operators):
    ``gx`` and ``gy`` 2-D of one shape, as :func:`magnitude_direction` takes them.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.descriptor import DescriptorParams, descriptor, prepare_from_gradients
    >>> p = DescriptorParams()
    >>> prep = prepare_from_gradients(np.zeros((8, 10)), np.full((8, 10), 0.1))   # all along y
    >>> bool(np.allclose(prep.M, 0.1)), bool(np.allclose(prep.Theta, 0.5))
    (True, True)
    >>> h2 = descriptor(prep, channels=slice(p.n_bins, 2 * p.n_bins), weighted=False)
    >>> k = int(prep.t_idx0[0, 0])                          # the direction bin of Theta = 0.5
    >>> bool(np.allclose(h2[k], 1.0)), bool(np.allclose(np.delete(h2, k, axis=0), 0.0))
    (True, True)
    """
    params = params_of(params, "params", DescriptorParams)
    gx, gy = _gradient_pair(gx, gy, two_d=True)
    M, Theta = _magnitude_direction(gx, gy)
    return _prepare_from(params, np.full(gx.shape, np.nan), gx, gy, M, Theta)


def _prepare_from(params, In, gx, gy, M, Theta) -> PreparedDescriptor:
    m0, _, m1, _ = _bin_weights(M, params)
    t0, _, t1, _ = _bin_weights(Theta, params)
    a1, a3, sw = _edge_weights(M, params)
    return PreparedDescriptor(params, In, gx, gy, M, Theta, m0, m1, t0, t1, a1, a3, sw)


# --------------------------------------------------------------------------------------------
# Channel selection
# --------------------------------------------------------------------------------------------


def _channel_index(channels, n_channels: int) -> np.ndarray:
    if channels is None:
        return np.arange(n_channels)
    if isinstance(channels, slice):
        try:
            return np.arange(n_channels)[channels]
        except (TypeError, ValueError):  # a step of 0, bounds that are not integers
            raise InvalidInputError(f"channels must be a slice of integers (step not 0), got "
                                    f"{shown(channels)}") from None
    idx = np.asarray(channels)
    if idx.ndim == 0:
        idx = idx[None]
    if idx.ndim != 1 or not (np.issubdtype(idx.dtype, np.integer) or idx.size == 0):
        raise InvalidInputError("channels must be None, a slice or a 1-D integer index array")
    idx = idx.astype(np.int64)
    if idx.size and (idx.min() < -n_channels or idx.max() >= n_channels):
        raise InvalidInputError(f"channel index out of range for {n_channels} channels")
    return np.where(idx < 0, idx + n_channels, idx)


def _groups(params: DescriptorParams, sel: np.ndarray):
    """Yield ``(level, hist, bins, positions)`` for the groups a selection touches."""
    K = params.n_bins
    grp = sel // K  # level * 3 + hist
    for g in np.unique(grp):
        pos = np.nonzero(grp == g)[0]
        yield int(g) // 3, int(g) % 3, (sel[pos] % K).astype(np.int64), pos


# --------------------------------------------------------------------------------------------
# Reference implementation (numpy / scipy)
# --------------------------------------------------------------------------------------------


def _reference_group(prep: PreparedDescriptor, level: int, hist: int) -> np.ndarray:
    """All K bins of one histogram at one level, normalised (float64, (K, H, W))."""
    params = prep.params
    w = params.windows[level]
    g = _gaussian_window(w, params.sigma_g(w))
    if hist == 0:
        i0, i1, val = prep.m_idx0, prep.m_idx1, None
    else:
        i0, i1 = prep.t_idx0, prep.t_idx1
        val = prep.M if hist == 2 else None
    K = params.n_bins
    H, W = prep.shape
    out = np.empty((K, H, W), dtype=np.float64)
    for k in range(K):
        ind = (i0 == k).astype(np.float64) + (i1 == k)  # weight 1 in each bin it falls in
        if val is not None:
            ind *= val
        t = ndimage.correlate1d(ind, g, axis=0, mode="nearest")
        out[k] = ndimage.correlate1d(t, g, axis=1, mode="nearest")
    total = out.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(total > 0, 1.0 / np.where(total > 0, total, 1.0), 0.0)
    out *= scale
    return out


def descriptor_reference(image, params: DescriptorParams | None = None, channels=None,
                         weighted: bool = True) -> np.ndarray:
    """Plain numpy/scipy descriptor (the readable reference); same contract as :func:`descriptor`.

    For every needed (level, histogram) group it builds the K per-bin indicator maps
    (``[Q(u) in bin k]``, times ``M(u)`` for h3), filters them with the separable Gaussian
    window (``correlate1d``, ``mode='nearest'`` = replicate border), divides by their sum over
    ``k`` and multiplies by the edge weight.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.descriptor import DescriptorParams, descriptor_reference
    >>> img = np.random.default_rng(2).random((16, 20)) + 0.5
    >>> D = descriptor_reference(img)
    >>> D.shape, D.dtype.name, DescriptorParams().n_channels
    ((612, 16, 20), 'float32', 612)
    >>> level = D.reshape(3, 204, 16, 20).sum(axis=1)       # D_p(w) of each window sums to 1
    >>> bool(np.allclose(level, 1.0, atol=1e-5))
    True
    """
    weighted = flag(weighted, "weighted")
    prep = prepare(image, params)
    params = prep.params
    sel = _channel_index(channels, params.n_channels)
    H, W = prep.shape
    out = np.empty((sel.size, H, W), dtype=np.float32)
    for level, hist, bins, pos in _groups(params, sel):
        h = _reference_group(prep, level, hist)[bins]
        if weighted:
            h *= (prep.a3 if hist == 2 else prep.a1)[None]
        out[pos] = h
    return out


# --------------------------------------------------------------------------------------------
# Fast implementation (numba kernel in hyperlf._descriptor_kernels)
# --------------------------------------------------------------------------------------------


def _descriptor_numba(prep: PreparedDescriptor, sel: np.ndarray, weighted: bool) -> np.ndarray:
    from . import _descriptor_kernels
    params = prep.params
    K = params.n_bins
    H, W = prep.shape
    ones = np.ones((H, W), dtype=np.float64)
    # channels requested more than once are computed once and copied afterwards
    uniq, inverse = np.unique(sel, return_inverse=True)
    out = np.empty((uniq.size, H, W), dtype=np.float32)
    for level, hist, bins, pos in _groups(params, uniq):
        w = params.windows[level]
        g = _gaussian_window(w, params.sigma_g(w))
        dest = np.full(K, -1, dtype=np.int64)
        dest[bins] = pos
        if hist == 0:
            i0, i1 = prep.m_idx0, prep.m_idx1
        else:
            i0, i1 = prep.t_idx0, prep.t_idx1
        a = (prep.a3 if hist == 2 else prep.a1) if weighted else ones
        _descriptor_kernels.hist_kernel(i0, i1, prep.M, hist == 2, g, K, a, dest, out)
    if uniq.size == sel.size and np.array_equal(uniq, sel):
        return out
    return out[inverse.ravel()]


# --------------------------------------------------------------------------------------------
# Public entry points
# --------------------------------------------------------------------------------------------


def descriptor(image, params: DescriptorParams | None = None, channels=None, impl: str = "auto",
               weighted: bool = True) -> np.ndarray:
    """Descriptor channels of one view, float32 ``(n_sel, H, W)``.

    Parameters
    ----------
    image : (H, W) array or PreparedDescriptor
        A view (any real dtype, linear intensity, positive mean), or the result of
        :func:`prepare` to avoid recomputing the per-view inputs when streaming blocks.
    params : DescriptorParams, optional
        Default ``DescriptorParams.default()``; ``DescriptorParams.paper()`` for the literal one.
    channels : None, slice or 1-D int array
        Which channels (order kept, duplicates allowed); None = all ``params.n_channels``.
    impl : "auto", "numba" or "numpy"
        ``"numpy"`` is :func:`descriptor_reference`; ``"auto"`` uses numba.
    weighted : bool
        False returns the bare normalised histograms ``h1, h2, h3`` (without ``a1, a2, a3``).

    Returns
    -------
    float32 (n_sel, H, W)
        Channel ``i`` is ``channels[i]`` (channel order: module docstring).

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.descriptor import descriptor
    >>> img = np.random.default_rng(0).random((16, 20)) + 0.5
    >>> h1 = descriptor(img, channels=slice(0, 68), weighted=False)  # first level's h1
    >>> h1.shape, bool(np.allclose(h1.sum(axis=0), 1.0, atol=1e-5))  # each histogram sums to 1
    ((68, 16, 20), True)
    """
    choice(impl, "impl", _IMPLS)
    weighted = flag(weighted, "weighted")
    prep = prepare(image, params)
    if impl == "numpy":
        return descriptor_reference(prep, channels=channels, weighted=weighted)
    sel = _channel_index(channels, prep.params.n_channels)
    return _descriptor_numba(prep, sel, weighted)


def iter_descriptor_blocks(image, params: DescriptorParams | None = None, block: int = 64,
                           impl: str = "auto", weighted: bool = True
                           ) -> Iterator[tuple[slice, np.ndarray]]:
    """Yield ``(channel_slice, array)`` blocks of at most ``block`` channels, in order.

    The per-view inputs are computed once.  Channels are computed one (level, histogram) group
    of ``n_bins`` channels at a time and each group exactly once, even when ``block`` is not a
    multiple of ``n_bins``; the memory held is one block plus one group
    (``(block + n_bins) * H * W * 4`` bytes; 88 MB at 450 x 375 with the defaults).  With
    ``block == n_bins`` (68) blocks coincide with groups and nothing is copied.  The yielded
    arrays are fresh (never reused or modified afterwards).

    Parameters
    ----------
    image, params, impl, weighted
        As :func:`descriptor`.
    block : int
        Channels per block (>= 1).

    Yields
    ------
    (slice, float32 (n, H, W))
        The channel range and its maps.

    Raises
    ------
    InvalidInputError
        At the call (before the first block): a bad image, ``params``, ``block``, ``impl`` or
        ``weighted``.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.descriptor import descriptor_reference, iter_descriptor_blocks
    >>> img = np.random.default_rng(3).random((16, 20)) + 0.5
    >>> blocks = list(iter_descriptor_blocks(img, block=100, impl="numpy"))
    >>> [(s.start, s.stop) for s, _ in blocks][-2:], blocks[-1][1].shape
    ([(500, 600), (600, 612)], (12, 16, 20))
    >>> whole = np.concatenate([b for _, b in blocks])
    >>> bool(np.array_equal(whole, descriptor_reference(img)))
    True
    """
    block = integer(block, "block", 1)
    choice(impl, "impl", _IMPLS)
    weighted = flag(weighted, "weighted")
    return _blocks(prepare(image, params), block, impl, weighted)


def _blocks(prep: PreparedDescriptor, block: int, impl: str, weighted: bool
            ) -> Iterator[tuple[slice, np.ndarray]]:
    """The blocks of :func:`iter_descriptor_blocks`, of checked arguments."""
    K = prep.params.n_bins
    n = prep.params.n_channels
    H, W = prep.shape
    cached_g, cached = -1, None
    for start in range(0, n, block):
        stop = min(start + block, n)
        if start % K == 0 and stop == start + K:  # exactly one group
            cached_g, cached = -1, None
            yield slice(start, stop), descriptor(prep, channels=slice(start, stop), impl=impl,
                                                 weighted=weighted)
            continue
        out = np.empty((stop - start, H, W), dtype=np.float32)
        c = start
        while c < stop:
            g = c // K
            gend = min((g + 1) * K, stop)
            if g != cached_g:
                cached = descriptor(prep, channels=slice(g * K, (g + 1) * K), impl=impl,
                                    weighted=weighted)
                cached_g = g
            out[c - start:gend - start] = cached[c - g * K:gend - g * K]
            c = gend
        yield slice(start, stop), out
