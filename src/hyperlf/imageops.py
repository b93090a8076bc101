"""Small per-image operations shared by the matching costs and the H-LF cues.

* :func:`normalise_intensity`: ``In = I / mean(I)`` (SPEC §3), the intensity normalisation of
  every cost and cue, so that views behind different filters (different exposure) compare.
* :func:`gradient_magnitude`: ``|grad In|`` with central differences and replicated borders.
* :func:`fill_masked`: every invalid pixel (validity mask, SPEC §11) takes the value of the
  nearest valid pixel, the masked analogue of the replicated border: window costs that reach
  into a region without data see its edge continued, not black.
"""

from __future__ import annotations

import numpy as np

from .errors import InvalidInputError

__all__ = ["normalise_intensity", "gradient_magnitude", "fill_masked"]


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
    a = np.asarray(image, dtype=dtype)
    if valid is not None and np.any(valid):
        m = float(a[np.broadcast_to(np.asarray(valid, bool), a.shape)].mean())
    elif valid is not None:
        m = float(a.mean()) if float(a.mean()) > 0 else 1.0
    else:
        m = float(a.mean())
    if not m > 0:
        raise InvalidInputError(
            f"image mean must be positive to normalise I / mean(I), got {m!r} "
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
    p = np.pad(image, 1, mode="edge")
    gx = (p[1:-1, 2:] - p[1:-1, :-2]) / 2.0
    gy = (p[2:, 1:-1] - p[:-2, 1:-1]) / 2.0
    return np.sqrt(gx * gx + gy * gy)


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

    a = np.array(image, dtype=np.float64)
    v = np.asarray(valid, bool)
    if v.shape != a.shape:
        raise InvalidInputError(f"mask shape {v.shape} does not match the image {a.shape}")
    if v.all() or not v.any():
        return a
    idx = distance_transform_edt(~v, return_distances=False, return_indices=True)
    return a[tuple(idx)]
