"""hyperlf: hyperspectral light field stereo matching, cube completion and rendering.

The public API is small and stable:

* :class:`hyperlf.LightField` — the data model (SPEC §1);
* :func:`hyperlf.load` / :func:`hyperlf.save` — read and write any supported format;
* :func:`hyperlf.stereo` — cross-spectral two-view stereo (:mod:`hyperlf.twoview`, SPEC §4);
* :func:`hyperlf.depth` — H-LF depth of the reference view (:mod:`hyperlf.hlf`, SPEC §5);
* :func:`hyperlf.complete` — plenoptic cube completion (:mod:`hyperlf.completion`, SPEC §7);
* :mod:`hyperlf.render` — colour emulation, refocusing, all-focus (SPEC §8);
* :mod:`hyperlf.spectral`, :mod:`hyperlf.synthesis`, :mod:`hyperlf.metrics`,
  :mod:`hyperlf.baselines` — tools.

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
    "stereo",
    "depth",
    "complete",
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


def stereo(left, right, disparity_range, **kwargs):
    """Cross-spectral two-view stereo; see :func:`hyperlf.twoview.stereo`."""
    from .twoview import stereo as _stereo

    return _stereo(left, right, disparity_range, **kwargs)


def depth(lightfield, **kwargs):
    """Disparity of an H-LF's reference view; see :func:`hyperlf.hlf.depth`."""
    from .hlf import depth as _depth

    return _depth(lightfield, **kwargs)


def complete(lightfield, disparity=None, out_path=None, **kwargs):
    """Plenoptic cube completion; see :func:`hyperlf.completion.complete`."""
    from .completion import complete as _complete

    return _complete(lightfield, disparity, out_path, **kwargs)
