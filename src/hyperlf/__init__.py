"""hyperlf: hyperspectral light field stereo matching, cube completion and rendering.

The public API is small and stable:

* :class:`hyperlf.LightField` — the data model (SPEC §1);
* :func:`hyperlf.load` / :func:`hyperlf.save` — read and write any supported format;
* :mod:`hyperlf.spectral`, :mod:`hyperlf.synthesis`, :mod:`hyperlf.metrics` — tools.

Heavy modules (colour-science, numba kernels) are imported lazily.
"""

from __future__ import annotations

from .errors import DataNotFoundError, FormatError, HyperLFError, InvalidInputError
from .lightfield import LightField, filter_layout, raster_wavelengths

__version__ = "0.1.0"

__all__ = [
    "LightField",
    "load",
    "save",
    "raster_wavelengths",
    "filter_layout",
    "HyperLFError",
    "InvalidInputError",
    "FormatError",
    "DataNotFoundError",
    "__version__",
]


def load(path, **kwargs):
    """Load a light field from a capture folder, an HDF5 file or an HCI scene folder.

    See :func:`hyperlf.formats.load_lightfield`.
    """
    from .formats import load_lightfield

    return load_lightfield(path, **kwargs)


def save(lightfield, path, **kwargs):
    """Save a light field as a capture folder (default) or HDF5 file (``.h5``/``.hdf5``).

    See :func:`hyperlf.formats.save_lightfield`.
    """
    from .formats import save_lightfield

    return save_lightfield(lightfield, path, **kwargs)
