"""The cost registry: every matching cost is one :class:`Cost` object, found by name.

Two-view stereo (:mod:`hyperlf.twoview`), H-LF depth (:mod:`hyperlf.hlf`), cube completion and
the command line all look costs up here (:func:`get_cost`, :func:`cost_names`), so adding a
cost means writing one :class:`Cost` subclass and registering an instance
(:func:`register_cost`); see ``docs/developers.md``.

A cost knows

* its ``name`` and a one-line ``description``;
* ``window``: the window its evaluators use when none is given (None: the evaluator decides);
* ``windows``: the default window per optimiser for two-view stereo (None: ``window``);
* ``params``: default optimiser parameters per optimiser for two-view stereo, plain dicts
  keyed by optimiser name (an optimiser that is not listed uses its own fallback);
* :meth:`Cost.pair_volume`: the rectified-pair volume at integer disparities;
* :meth:`Cost.view_volume`: the per-view light-field volume at sub-pixel shifts (a cost
  without one is not available for light fields);
* :meth:`Cost.pair_volumes`: left- and right-referenced volumes for the left-right check.

:class:`FusedCost` combines registered costs: ``sum_i w_i norm(C_i) / sum_i w_i``
(:func:`hyperlf.costs.fuse`).
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Mapping
from typing import Any, Iterator, Sequence

import numpy as np

from .._options import choice, flag, integer, mapping, shown
from ..errors import InvalidInputError
from ._validate import IMPLS, check_window
from .pair import fuse, right_validity, row_moments, weights_tuple

__all__ = [
    "Cost",
    "FusedCost",
    "AUTO_METRIC",
    "register_cost",
    "unregister_cost",
    "registered_cost",
    "get_cost",
    "cost_names",
    "resolve_metric",
    "fusion_weights",
    "cost_volume",
    "cost_volumes",
    "METRICS",
]

#: What ``"auto"`` means, for two-view stereo and H-LF depth alike (decision and its measurements:
#: BENCHMARKS.md, Tables 1 and 2).
AUTO_METRIC = "census-rsncc"

_REGISTRY: dict[str, "Cost"] = {}


class Cost:
    """A matching cost: name, defaults, and its two evaluators.

    Subclass it, set the class attributes, implement :meth:`pair_volume` and (for light
    fields) :meth:`view_volume`, and register an instance with :func:`register_cost`.

    Attributes
    ----------
    name : str
        Registry key (lower case; ``"auto"`` is reserved).
    description : str
        One line, shown in listings.
    window : int or None
        Window the evaluators use when called with ``window=None``.
    windows : dict
        Default window per optimiser for two-view stereo, e.g. ``{"graphcut": 9}``; a missing
        optimiser (or None) means ``window``'s rule (the stereo result records None then).
    dense_window : int or None
        Window of the light-field form when the reference has many other views to average
        over (:func:`light_field_window`); None: :attr:`window` whatever the array.
    params : dict
        Default optimiser parameters per optimiser for two-view stereo, e.g.
        ``{"graphcut": {"weight": 4.0}, "sgm": {"p1": 2.0, "p2": 16.0}}``, merged over the
        optimiser's own fallback.
    """

    name: str = ""
    description: str = ""
    window: int | None = None
    windows: dict = {}
    dense_window: int | None = None
    params: dict = {}

    # -- defaults ---------------------------------------------------------------------------

    def default_window(self, optimiser: str) -> int | None:
        """The two-view default window for ``optimiser`` (None: the cost's own default)."""
        return self.windows.get(optimiser, None)

    def window_for(self, window: int | None) -> int | None:
        """The window an evaluator uses: ``window``, or the cost's own :attr:`window` if None."""
        return self.window if window is None else window

    def default_params(self, optimiser: str) -> dict:
        """The cost's own optimiser parameters for ``optimiser`` (a fresh copy; may be empty)."""
        return dict(self.params.get(optimiser, {}))

    @property
    def light_field(self) -> bool:
        """True when the cost has a light-field evaluator (:meth:`view_volume`)."""
        return type(self).view_volume is not Cost.view_volume

    # -- evaluators -------------------------------------------------------------------------

    def pair_volume(self, left, right, dmin: int, dmax: int, *, window: int | None = None,
                    impl: str = "auto", **options) -> np.ndarray:
        """Cost volume of a rectified pair, float32 ``(dmax - dmin + 1, H, W)``.

        Left ``x`` vs right ``x - d``; lower is better; out-of-image candidates carry the
        pixel's worst valid cost (:func:`hyperlf.costs.fill_out_of_image`).
        """
        raise NotImplementedError

    #: True for a cost whose light-field volume is scaled by statistics of the whole volume
    #: (a fusion's normalisers): a strip of rows then needs them from :meth:`view_moments`.
    global_scales = False

    def view_volume(self, ref_img, img, shifts, *, window: int | None = None, valid=None,
                    rows=None, **options) -> np.ndarray:
        """Light-field volume of one view, float32 ``(len(shifts), H, W)``.

        ``img`` is sampled bilinearly at ``p + (sx, sy)`` for each shift and compared with
        ``ref_img`` at ``p``.  ``valid`` is the in-image mask of the samples; ``options``
        (``tau_rel``, ``eps``, ``block``, ``cache`` from :func:`hyperlf.costs.view_costs`) may
        be ignored.  Invalid entries may hold anything: the caller fills them.  ``rows``
        ``(a, b)``: only those reference rows, ``(len(shifts), b - a, W)``, exactly as the
        whole image has them (``valid`` is then the strip's).
        """
        raise InvalidInputError(f"cost {self.name!r} is not available for light fields; "
                                f"choose one of {', '.join(cost_names(light_field=True))}")

    def view_moments(self, ref_img, img, shifts, *, window: int | None = None, valid=None,
                     rows=None, **options):
        """For a cost with :attr:`global_scales`: per part, the
        :func:`hyperlf.costs.row_moments` of the strip ``rows`` (arguments as
        :meth:`view_volume`); None otherwise."""
        return None

    def pair_volumes(self, left, right, dmin: int, dmax: int, *, window: int | None = None,
                     impl: str = "auto", need_right: bool = True, **options):
        """Left- and right-referenced volumes ``(C_L, C_R)``; ``C_R`` is None unless
        ``need_right``.

        ``C_R[d, y, x_r] = C_L[d, y, x_r + d]``: exact for every cost that compares the left
        patch around ``x`` with the right patch around ``x - d``, each with its own replicated
        border (the pair's cost does not depend on which view is the reference).
        """
        cl = self.pair_volume(left, right, dmin, dmax, window=window, impl=impl, **options)
        cl = np.asarray(cl, dtype=np.float32)
        return cl, (_right_from_left(cl, dmin) if need_right else None)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}>"


def _right_from_left(volume, dmin: int) -> np.ndarray:
    from ..regularisers import right_cost_from_left
    labels = np.arange(dmin, dmin + volume.shape[0], dtype=np.float64)
    return right_cost_from_left(volume, labels)


class FusedCost(Cost):
    """Weighted mean of normalised volumes of registered costs (SPEC §3 fusion).

    ``C = sum_i w_i norm(C_i) / sum_i w_i`` (:func:`hyperlf.costs.fuse`).  Options of
    :meth:`pair_volume`: ``<part>_window`` (each part's window, default the part's
    ``window``), ``weights``, ``impl``; any other option goes to the first part, over the
    fusion's own ``part_options``.  A plain
    ``window`` is ignored by the pair volume; for the light-field volume it sets the window of
    part ``view_window_part`` (None: ignored there too).

    The normalisation subtracts a *per-pixel* minimum, which is referenced to one view, so the
    right-referenced volume is not a shift of the fused left one: :meth:`pair_volumes` shifts
    the raw parts and fuses them again with the right view's validity, which is exact.

    Parameters
    ----------
    name, description : str
    parts : sequence of str
        Names of registered costs.
    weights : sequence of float
        One per part (default all 1), each finite and >= 0, not all 0, with a finite sum;
        the pair and the light-field volumes also take ``weights=`` per call
        (:meth:`check_weights`).
    view_window_part : int, optional
        Which part a light-field ``window`` applies to.
    part_options : mapping, optional
        Part name -> options of that part's pair volume (e.g. ``{"census": {"support_gamma":
        0.1}}``); the light-field volumes take none.
    params, windows : dict, optional
        As :class:`Cost`.
    """

    def __init__(self, name: str, parts: Sequence[str], *, weights: Sequence[float] | None = None,
                 description: str = "", view_window_part: int | None = None,
                 params: dict | None = None, windows: dict | None = None,
                 part_options: Mapping[str, Mapping] | None = None):
        self.name = _cost_name(name)
        if isinstance(parts, (str, bytes, Mapping, np.ndarray)) or \
                not isinstance(parts, Sequence) or not parts or \
                not all(isinstance(p, str) and p for p in parts):
            raise InvalidInputError(f"{name}: parts must be a sequence of registered cost "
                                    f"names, got {shown(parts)}")
        self.parts = tuple(parts)
        if not isinstance(description, str):
            raise InvalidInputError(f"{name}: description must be a string, got "
                                    f"{shown(description)}")
        if view_window_part is not None:
            view_window_part = integer(view_window_part, "view_window_part",
                                       maximum=len(self.parts) - 1)
        for label, value in (("params", params), ("windows", windows)):
            mapping(value, f"{name}: {label}")
        mapping(part_options, f"{name}: part_options")
        for p, o in (part_options or {}).items():
            mapping(o, f"{name}: part_options[{p!r}]", optional=False)
        self.part_options = {p: dict(o) for p, o in (part_options or {}).items()}
        mapping(self.part_options, f"{name}: part_options", keys=self.parts,
                taker=f"{name} (its parts)")
        self.weights = self.check_weights(weights) if weights is not None \
            else (1.0,) * len(self.parts)
        self.description = description
        self.view_window_part = view_window_part
        self.params = dict(params or {})
        self.windows = dict(windows or {})

    @property
    def light_field(self) -> bool:
        return all(get_cost(p).light_field for p in self.parts)

    @property
    def dense_window(self) -> int | None:
        """The dense-array window of part ``view_window_part`` (None without one)."""
        if self.view_window_part is None:
            return None
        return get_cost(self.parts[self.view_window_part]).dense_window

    def _part_volumes(self, left, right, dmin, dmax, impl, options):
        opts = dict(options)
        part_windows = [opts.pop(f"{p}_window", get_cost(p).window) for p in self.parts]
        weights = self.check_weights(opts.pop("weights", self.weights))
        vols = []
        for i, (p, w) in enumerate(zip(self.parts, part_windows)):
            extra = {**self.part_options.get(p, {}), **(opts if i == 0 else {})}
            vols.append(get_cost(p).pair_volume(left, right, dmin, dmax, window=w, impl=impl,
                                                **extra))
        return vols, weights

    def pair_volume(self, left, right, dmin, dmax, *, window=None, impl="auto", **options):
        vols, weights = self._part_volumes(left, right, dmin, dmax, impl, options)
        return fuse(vols, weights, dmin, overwrite=True)

    def pair_volumes(self, left, right, dmin, dmax, *, window=None, impl="auto",
                     need_right=True, **options):
        vols, weights = self._part_volumes(left, right, dmin, dmax, impl, options)
        if not need_right:
            return fuse(vols, weights, dmin, overwrite=True), None
        rights = [_right_from_left(v, dmin) for v in vols]  # before the left fuse writes over vols
        cl = fuse(vols, weights, dmin, overwrite=True)
        vr = right_validity(cl.shape[1:], dmin, dmax)
        return cl, fuse(rights, weights, dmin, valid=vr, overwrite=True)

    global_scales = True

    def _view_parts(self, ref_img, img, shifts, window, valid, options):
        for i, p in enumerate(self.parts):
            w = window if i == self.view_window_part else None
            yield get_cost(p).view_volume(ref_img, img, shifts, window=w, valid=valid, **options)

    #: How each part of one view's volume is centred before the parts are added
    #: (``centre`` of :func:`hyperlf.costs.normalise_volume`): not at all, so that a view's
    #: cost at a label does not depend on the other labels at which it sees the pixel.  A
    #: per-pixel minimum is taken over those labels, and a view that sees fewer (near the image
    #: border, behind a mask) subtracts a higher one: the average over views then favoured the
    #: labels at which such views count, and a textureless region by the border drifted to a
    #: range limit.  (The mean over those labels, ``"mean"``, was measured too: BENCHMARKS.md.)
    view_centre = "none"

    def view_volume(self, ref_img, img, shifts, *, window=None, valid=None, scales=None,
                    weights=None, **options):
        """The fused volume; ``scales`` (one per part): the normalisers' standard deviations
        when measured on the whole view (a strip of ``rows``), else measured here;
        ``weights`` (one per part): instead of :attr:`weights` (:meth:`check_weights`).  The
        parts are centred by :attr:`view_centre`."""
        weights = self.weights if weights is None else self.check_weights(weights)
        vols = list(self._view_parts(ref_img, img, shifts, window, valid, options))
        return fuse(vols, weights, dmin=0, valid=valid, scales=scales, overwrite=True,
                    centre=self.view_centre)

    def check_weights(self, weights) -> tuple:
        """``weights`` as a tuple of floats, one per part, each finite and >= 0, not all 0,
        with a finite sum.

        Raises
        ------
        InvalidInputError
            Otherwise (the message names the parts).
        """
        w = weights_tuple(weights)
        if w is None or len(w) != len(self.parts):
            raise InvalidInputError(
                f"{self.name} needs {len(self.parts)} weights, one per part "
                f"({', '.join(self.parts)}), each finite and >= 0, not all 0, with a finite "
                f"sum; got "
                f"{shown(weights)}")
        return w

    def view_moments(self, ref_img, img, shifts, *, window=None, valid=None, **options):
        """Per part, :func:`hyperlf.costs.row_moments` of its raw volume on the strip."""
        return [row_moments(v, valid)
                for v in self._view_parts(ref_img, img, shifts, window, valid, options)]


# --------------------------------------------------------------------------------------------
# Registry
# --------------------------------------------------------------------------------------------


def register_cost(cost: Cost, *, replace: bool = False) -> Cost:
    """Add ``cost`` to the registry under ``cost.name`` and return it.

    Raises
    ------
    InvalidInputError
        Not a :class:`Cost`, a bad name (empty, ``"auto"``, not lower case), or a name that is
        taken (unless ``replace``).

    Examples
    --------
    A cost of one's own, the absolute difference of single pixels (left ``x`` against right
    ``x - d``), registered, used by name like a built-in one, then removed again.  On a random
    texture and its copy moved 3 px to the right it is 0 at disparity 3 and above 0 at every
    other, from column 3 on (the columns ``np.roll`` wrapped round are left out):

    >>> import numpy as np
    >>> from hyperlf.costs import (Cost, cost_names, cost_volume, fill_out_of_image,
    ...                            register_cost, shift_cols, unregister_cost)
    >>> class AbsDiff(Cost):
    ...     name = "absdiff"
    ...     description = "absolute difference of single pixels"
    ...     def pair_volume(self, left, right, dmin, dmax, **options):
    ...         ds = range(dmin, dmax + 1)
    ...         C = np.stack([np.abs(left - shift_cols(right, d)) for d in ds])
    ...         return fill_out_of_image(C.astype(np.float32), dmin)
    >>> before = cost_names()
    >>> register_cost(AbsDiff())
    <AbsDiff 'absdiff'>
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> C = cost_volume(np.roll(right, 3, axis=1), right, 0, 6, metric="absdiff")
    >>> float(C[3, :, 3:].max()), float(np.delete(C, 3, axis=0)[:, :, 3:].min()) > 0
    (0.0, True)
    >>> unregister_cost("absdiff")
    <AbsDiff 'absdiff'>
    >>> cost_names() == before
    True
    """
    if not isinstance(cost, Cost):
        raise InvalidInputError(f"register_cost needs a Cost instance, got {type(cost).__name__}")
    name = _cost_name(cost.name)
    replace = flag(replace, "replace")
    if name in _REGISTRY and not replace:
        raise InvalidInputError(f"a cost named {name!r} is already registered")
    _REGISTRY[name] = cost
    return cost


def _cost_name(name) -> str:
    """``name`` when it can name a cost: a non-empty lower-case string other than 'auto'."""
    if not isinstance(name, str) or not name or name != name.strip().lower() or name == "auto":
        raise InvalidInputError(f"cost name must be a non-empty lower-case string other than "
                                f"'auto', got {shown(name)}")
    return name


def unregister_cost(name: str) -> Cost:
    """Remove the cost ``name`` from the registry and return it.

    Raises
    ------
    InvalidInputError
        ``"auto"`` or a name that is not registered.

    Examples
    --------
    The name is taken case-insensitively, and the removed cost is returned:

    >>> import numpy as np
    >>> from hyperlf.costs import Cost, cost_names, register_cost, unregister_cost
    >>> class Flat(Cost):
    ...     name = "flat"
    ...     def pair_volume(self, left, right, dmin, dmax, **options):
    ...         return np.zeros((dmax - dmin + 1,) + np.shape(left), np.float32)
    >>> flat = register_cost(Flat())
    >>> "flat" in cost_names(), unregister_cost("FLAT") is flat, "flat" in cost_names()
    (True, True, False)
    """
    key = name.strip().lower() if isinstance(name, str) else None
    if key is None or key == "auto" or key not in _REGISTRY:
        raise InvalidInputError(f"no registered cost named {shown(name)}; registered: "
                                f"{_choices(False)}")
    return _REGISTRY.pop(key)


@contextlib.contextmanager
def registered_cost(cost: Cost) -> Iterator[Cost]:
    """Context manager: ``cost`` is registered inside the block, unregistered after it.

    Examples
    --------
    A cost that is the same at every disparity, there only for the ``with`` block; its volume
    has ``dmax - dmin + 1 = 4`` labels:

    >>> import numpy as np
    >>> from hyperlf.costs import Cost, cost_names, cost_volume, registered_cost
    >>> class Flat(Cost):
    ...     name = "flat"
    ...     def pair_volume(self, left, right, dmin, dmax, **options):
    ...         return np.zeros((dmax - dmin + 1,) + np.shape(left), np.float32)
    >>> with registered_cost(Flat()):
    ...     print("flat" in cost_names())
    ...     C = cost_volume(np.ones((4, 6)), np.ones((4, 6)), -1, 2, metric="flat")
    True
    >>> C.shape, "flat" in cost_names()
    ((4, 4, 6), False)
    """
    register_cost(cost)
    try:
        yield cost
    finally:
        _REGISTRY.pop(cost.name, None)


def cost_names(*, light_field: bool = False) -> tuple[str, ...]:
    """Names of the registered costs, in registration order (``"auto"`` not included).

    ``light_field=True``: only the costs with a light-field evaluator.

    Examples
    --------
    The built-in costs; all but ``ssd`` have a light-field form:

    >>> from hyperlf.costs import cost_names
    >>> cost_names()
    ('ssd', 'ncc', 'rsncc', 'census', 'bwncc', 'bwncc-paper', 'fused', 'census-rsncc')
    >>> sorted(set(cost_names()) - set(cost_names(light_field=True)))
    ['ssd']
    """
    light_field = flag(light_field, "light_field")
    return tuple(n for n, c in _REGISTRY.items() if not light_field or c.light_field)


def _choices(light_field: bool) -> str:
    return ", ".join(cost_names(light_field=light_field) + ("auto",))


def get_cost(name: str, *, light_field: bool = False) -> Cost:
    """The registered cost ``name`` (case-insensitive; ``"auto"`` -> :data:`AUTO_METRIC`).

    Raises
    ------
    InvalidInputError
        Not a string, an unknown name (the message lists the choices), or, with
        ``light_field=True``, a cost without a light-field evaluator.

    Examples
    --------
    >>> from hyperlf.costs import AUTO_METRIC, get_cost
    >>> get_cost("Census").name, get_cost("census").window, get_cost("auto").name == AUTO_METRIC
    ('census', 7, True)
    >>> get_cost("ssd", light_field=True)
    Traceback (most recent call last):
        ...
    hyperlf.errors.InvalidInputError: metric 'ssd' is not available for H-LF matching; ...
    """
    if not isinstance(name, str):
        raise InvalidInputError(
            f"metric must be a string, one of {cost_names() + ('auto',)}, got {shown(name)}")
    light_field = flag(light_field, "light_field")
    key = name.strip().lower()
    if key == "auto":
        key = AUTO_METRIC
    cost = _REGISTRY.get(key)
    if cost is None:
        raise InvalidInputError(f"unknown metric {name!r}; choose one of {_choices(False)}")
    if light_field and not cost.light_field:
        raise InvalidInputError(
            f"metric {name!r} is not available for H-LF matching; choose one of "
            f"{', '.join(cost_names(light_field=True))} or 'auto'")
    return cost


def resolve_metric(name: str) -> str:
    """Return the concrete cost name (``"auto"`` -> :data:`AUTO_METRIC`).

    Examples
    --------
    >>> from hyperlf.costs import AUTO_METRIC, resolve_metric
    >>> resolve_metric("auto") == AUTO_METRIC, resolve_metric(" NCC ")
    (True, 'ncc')
    """
    return get_cost(name).name


def fusion_weights(name: str, weights) -> tuple:
    """``weights`` checked for the fused cost ``name``: one float per part, in its order.

    Raises
    ------
    InvalidInputError
        ``name`` is not a fusion (one cost has nothing to weight), or the weights are not
        one finite number >= 0 per part, not all 0, with a finite sum.

    Examples
    --------
    >>> from hyperlf.costs import fusion_weights
    >>> fusion_weights("auto", [1, 4])                    # census-rsncc: rsncc, census
    (1.0, 4.0)
    """
    cost = get_cost(name)
    if not isinstance(cost, FusedCost):
        fused = ", ".join(n for n in cost_names() if isinstance(_REGISTRY[n], FusedCost))
        raise InvalidInputError(f"fusion weights need a fused cost ({fused}), not "
                                f"{cost.name!r}")
    return cost.check_weights(weights)


class _MetricsView(Mapping):
    """Read-only live view ``{name: cost.pair_volume}`` of the registry."""

    def __getitem__(self, name: str):
        return _REGISTRY[name].pair_volume

    def __iter__(self):
        return iter(tuple(_REGISTRY))

    def __len__(self) -> int:
        return len(_REGISTRY)


#: ``{name: pair-volume function}`` for every registered cost (a live view of the registry).
METRICS: Mapping[str, Any] = _MetricsView()


@contextlib.contextmanager
def _bad_parameters(name: str):
    """An option the cost's volume function does not take, refused in one line that names it
    and says where the cost's options are documented."""
    try:
        yield
    except TypeError as e:  # unknown keyword for this cost
        found = re.search(r"(\w+)\(\) got an unexpected keyword argument (.*)$", str(e),
                          re.DOTALL)
        if found is None:
            raise
        func, option = found[1], shown(found[2].strip("'"))
        from . import pair

        where = f"hyperlf.costs.{func}" if hasattr(pair, func) else f"{func}()"
        cost, fused = get_cost(name), ""
        if isinstance(cost, FusedCost):
            windows = ", ".join(f"{p}_window" for p in cost.parts)
            fused = (f"; a fusion also takes weights and {windows}, and passes the rest to its "
                     f"first part")
        raise InvalidInputError(f"metric {name!r} has no option {option}: its options are "
                                f"those of {where}{fused}") from None


def _checked(metric, window, impl, image) -> tuple[Cost, int | None]:
    cost = get_cost(metric)
    if window is not None:
        window = check_window(window, side=max(np.shape(image)[:2], default=0))
    choice(impl, "impl", IMPLS)
    return cost, window


def cost_volume(left, right, dmin: int, dmax: int, metric: str = "auto", window: int | None = None,
                impl: str = "auto", return_valid: bool = False, **params):
    """Matching cost volume ``cost[L, H, W]`` float32 (lower is better) of a rectified pair.

    Parameters
    ----------
    left, right : (H, W) arrays
        Rectified pair; left pixel ``x`` matches right pixel ``x - d``, ``d = dmin..dmax``.
    metric : str
        A registered cost (:func:`cost_names`) or ``"auto"``.
    window : int, optional
        Odd window; None = the cost's own default.
    impl : "auto", "numpy" or "numba"
    return_valid : bool
        Also return the :func:`hyperlf.costs.candidate_validity` mask.
    **params
        Cost options, e.g. ``tau_rel``, ``rs_tau`` for rsncc, ``block``, ``tau_scope``,
        ``eps`` for bwncc, ``<part>_window`` and ``weights`` for fused costs.

    Raises
    ------
    InvalidInputError
        Unknown metric or option, bad window or impl, bad images.

    Examples
    --------
    >>> import numpy as np
    >>> from hyperlf.costs import cost_volume
    >>> rng = np.random.default_rng(0)
    >>> right = rng.random((20, 30)) + 0.5
    >>> left = np.roll(right, 3, axis=1)          # left x = right x - 3
    >>> C = cost_volume(left, right, 0, 6, metric="census")
    >>> C.shape, int(np.median(C.argmin(axis=0)))
    ((7, 20, 30), 3)
    """
    from .pair import candidate_validity
    cost, window = _checked(metric, window, impl, left)
    return_valid = flag(return_valid, "return_valid")
    with _bad_parameters(cost.name):
        vol = cost.pair_volume(left, right, dmin, dmax, window=window, impl=impl, **params)
    if return_valid:
        return vol, candidate_validity(vol.shape[1:], dmin, dmax)
    return vol


def cost_volumes(left, right, dmin: int, dmax: int, metric: str = "auto", *,
                 window: int | None = None, impl: str = "auto", need_right: bool = True,
                 **params):
    """Left- and right-referenced volumes ``(C_L, C_R)`` of a rectified pair.

    As :func:`cost_volume`; ``C_R[d, y, x_r]`` compares right ``x_r`` with left ``x_r + d``
    (:meth:`Cost.pair_volumes`), None unless ``need_right``.

    Examples
    --------
    The left image is the right one moved 3 px to the right.  The right-referenced volume is
    the left one read at ``x_r + d``, and it finds right pixel ``x_r`` at left ``x_r + 3`` on
    columns 3 to 17 (clear of the borders and of the columns ``np.roll`` wrapped round):

    >>> import numpy as np
    >>> from hyperlf.costs import cost_volumes
    >>> right = np.random.default_rng(0).random((16, 24)) + 0.5
    >>> left = np.roll(right, 3, axis=1)
    >>> C_L, C_R = cost_volumes(left, right, 0, 6, metric="census")
    >>> bool(np.array_equal(C_R[3, :, :-3], C_L[3, :, 3:]))
    True
    >>> np.unique(C_R.argmin(axis=0)[:, 3:-6]).tolist()
    [3]
    >>> cost_volumes(left, right, 0, 6, metric="census", need_right=False)[1] is None
    True
    """
    cost, window = _checked(metric, window, impl, left)
    need_right = flag(need_right, "need_right")
    with _bad_parameters(cost.name):
        return cost.pair_volumes(left, right, dmin, dmax, window=window, impl=impl,
                                 need_right=need_right, **params)
