"""Small per-image operations shared by the matching costs and the H-LF cues.

* :func:`normalise_intensity`: ``In = I / mean(I)`` (SPEC §3), the intensity normalisation of
  every cost and cue, so that views behind different filters (different exposure) compare.
* :func:`gradient_magnitude`: ``|grad In|`` with central differences and replicated borders.
"""

from __future__ import annotations

import numpy as np

from .errors import InvalidInputError

__all__ = ["normalise_intensity", "gradient_magnitude"]


def normalise_intensity(image, dtype=np.float64) -> np.ndarray:
    """Return ``image / mean(image)`` as ``dtype``.

    Parameters
    ----------
    image : array_like
        Linear intensities (any positive scale).
    dtype : numpy dtype, optional
        Working precision (float64).

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
