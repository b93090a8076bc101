"""hyperlf: hyperspectral light field stereo matching, cube completion and rendering.

The public API is small and stable:

* :class:`hyperlf.LightField` — the data model (SPEC §1);
* :func:`hyperlf.load` / :func:`hyperlf.save` — read and write any supported format;
* :func:`hyperlf.stereo` — cross-spectral two-view stereo (:mod:`hyperlf.twoview`, SPEC §4);
* :func:`hyperlf.depth` — H-LF depth of the reference view (:mod:`hyperlf.hlf`, SPEC §5);
* :func:`hyperlf.complete` — plenoptic cube completion (:mod:`hyperlf.completion`, SPEC §7);
* :mod:`hyperlf.render` — colour emulation, refocusing, all-focus (SPEC §8);
* :mod:`hyperlf.spectral`, :mod:`hyperlf.synthesis`, :mod:`hyperlf.metrics`,
  :mod:`hyperlf.baselines`, :mod:`hyperlf.pipeline` — tools.

Submodules are attached lazily with ``lazy_loader`` (as scikit-image does): ``import hyperlf``
is cheap (it imports neither numba, OpenCV, colour-science, matplotlib nor h5py) and
``hyperlf.render`` (or any other submodule) is imported on first attribute access.

Examples
--------
>>> import hyperlf
>>> hyperlf.__version__
'0.1.0'
>>> callable(hyperlf.render.emulate_camera)
True
"""

from __future__ import annotations

import lazy_loader as _lazy

from .errors import DataNotFoundError, FormatError, HyperLFError, InvalidInputError

__version__ = "0.1.0"

#: Submodules attached lazily (by module name: a flat module or a package both work).
_SUBMODULES = [
    "baselines",
    "calibration",
    "cli",
    "completion",
    "costs",
    "datasets",
    "descriptor",
    "errors",
    "formats",
    "hlf",
    "imageops",
    "lightfield",
    "metrics",
    "outputs",
    "pipeline",
    "regularisers",
    "render",
    "report",
    "spectral",
    "synthesis",
    "tiling",
    "twoview",
    "visualise",
    "warp",
]

#: Names of submodules offered at the top level, imported on first access as well, so that
#: ``import hyperlf`` does not import numpy (the ``hyperlf`` command installs its signal
#: handlers before any heavy import).
_ATTRIBUTES = {"lightfield": ["LightField", "filter_layout", "raster_wavelengths"]}

__getattr__, _lazy_dir, _ = _lazy.attach(__name__, submodules=_SUBMODULES,
                                         submod_attrs=_ATTRIBUTES)

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


def __dir__():
    return sorted(set(__all__) | set(_lazy_dir()))


def load(path, **kwargs):
    """Load a light field from a capture folder, an HDF5 file or an HCI scene folder.

    Parameters
    ----------
    path : str or path-like
        A capture folder (SPEC §2), an ``.h5``/``.hdf5`` file or an HCI 4D scene folder.
    **kwargs
        Passed to :func:`hyperlf.formats.load_lightfield`.

    Returns
    -------
    LightField
        The light field, views float32 in [0, 1].

    Examples
    --------
    >>> import tempfile, pathlib, hyperlf
    >>> from hyperlf.synthesis import procedural_scene
    >>> lf = procedural_scene(seed=1, rows=2, cols=2, height=16, width=20)
    >>> folder = pathlib.Path(tempfile.mkdtemp()) / "cap"
    >>> _ = hyperlf.save(lf, folder)
    >>> hyperlf.load(folder).views.shape
    (2, 2, 16, 20)
    """
    from .formats import load_lightfield

    return load_lightfield(path, **kwargs)


def save(lightfield, path, **kwargs):
    """Save a light field as a capture folder (default) or HDF5 file (``.h5``/``.hdf5``).

    Parameters
    ----------
    lightfield : LightField
        What to write.
    path : str or path-like
        Destination; the suffix ``.h5``/``.hdf5`` selects HDF5, anything else a capture folder.
    **kwargs
        Passed to :func:`hyperlf.formats.save_lightfield`.

    Returns
    -------
    pathlib.Path
        What was written.

    Examples
    --------
    >>> import tempfile, pathlib, hyperlf
    >>> import numpy as np
    >>> from hyperlf.synthesis import procedural_scene
    >>> lf = procedural_scene(seed=1, rows=2, cols=2, height=16, width=20)
    >>> path = hyperlf.save(lf, pathlib.Path(tempfile.mkdtemp()) / "scene.h5")
    >>> path.name, bool(np.array_equal(hyperlf.load(path).views, lf.views))
    ('scene.h5', True)
    """
    from .formats import save_lightfield

    return save_lightfield(lightfield, path, **kwargs)


def stereo(left, right, disparity_range, **kwargs):
    """Cross-spectral two-view stereo; see :func:`hyperlf.twoview.stereo`.

    Parameters
    ----------
    left, right : ndarray
        Rectified views of different spectral bands.
    disparity_range : tuple of int
        ``(d_min, d_max)`` in pixels.
    **kwargs
        Passed to :func:`hyperlf.twoview.stereo`.

    Returns
    -------
    hyperlf.twoview.StereoResult
        The disparity of the left view and its diagnostics.

    Examples
    --------
    A random texture and its copy 3 px to the left with the contrast inverted, as two bands
    may see one surface:

    >>> import numpy as np, hyperlf
    >>> from scipy.ndimage import gaussian_filter
    >>> texture = gaussian_filter(np.random.default_rng(0).random((40, 80)), 1.0)
    >>> left, right = texture[:, 10:70], 1.0 - texture[:, 13:73]
    >>> float(np.median(hyperlf.stereo(left, right, (0, 6)).disparity))
    3.0
    """
    from .twoview import stereo as _stereo

    return _stereo(left, right, disparity_range, **kwargs)


def depth(lightfield, **kwargs):
    """Disparity of an H-LF's reference view; see :func:`hyperlf.hlf.depth`.

    Parameters
    ----------
    lightfield : LightField
        The hyperspectral light field.
    **kwargs
        Passed to :func:`hyperlf.hlf.depth`.

    Returns
    -------
    hyperlf.hlf.DepthResult
        The reference-view disparity and its diagnostics.

    Examples
    --------
    Most reference pixels of a small procedural scene come within one label step of the
    truth:

    >>> import numpy as np, hyperlf
    >>> from hyperlf.synthesis import procedural_scene
    >>> lf = procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    >>> res = hyperlf.depth(lf, n_labels=16)  # 16 labels over (-2, 2): a step of 4 / 15 px
    >>> error = np.abs(res.disparity - lf.reference_gt_disparity)
    >>> res.disparity.shape, bool(np.median(error) < 4 / 15)
    ((32, 40), True)
    """
    from .hlf import depth as _depth

    return _depth(lightfield, **kwargs)


def complete(lightfield, disparity=None, out_path=None, **kwargs):
    """Plenoptic cube completion; see :func:`hyperlf.completion.complete`.

    Parameters
    ----------
    lightfield : LightField
        The hyperspectral light field.
    disparity : ndarray, optional
        Reference-view disparity; estimated with :func:`depth` when omitted.
    out_path : str or path-like, optional
        Where to write the cube (see :func:`hyperlf.completion.complete`).
    **kwargs
        Passed to :func:`hyperlf.completion.complete`.

    Returns
    -------
    hyperlf.completion.CompletionResult
        The completed cube (and where it was written).

    Examples
    --------
    Every view gets every band, and keeps its own exactly:

    >>> import numpy as np, hyperlf
    >>> from hyperlf.synthesis import procedural_scene
    >>> lf = procedural_scene(seed=1, rows=2, cols=2, height=16, width=20)
    >>> res = hyperlf.complete(lf, lf.reference_gt_disparity)
    >>> res.cube.shape, res.wavelengths.round().tolist()
    ((2, 2, 4, 16, 20), [410.0, 507.0, 603.0, 700.0])
    >>> all(np.array_equal(res.cube[r, c, res.band_index[r, c]], lf.views[r, c])
    ...     for r in range(2) for c in range(2))
    True
    """
    from .completion import complete as _complete

    return _complete(lightfield, disparity, out_path, **kwargs)
