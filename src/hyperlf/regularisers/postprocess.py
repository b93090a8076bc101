"""After the optimiser: occlusion handling, sub-pixel refinement, confidence, post-filter (SPEC §4)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..errors import InvalidInputError
from ..warp import coordinate_taps
from .._options import (array, bool_mask, check_fields, choice, flag, integer, number,
                        real_array, rule)
from ._checks import check_cost, check_label_map, check_labels, gather

__all__ = ["label_saving", "left_right_check", "left_occlusions", "fill_occlusions",
           "right_cost_from_left", "subpixel_refine",
           "confidence", "edge_confidence", "thin_foreground", "ConfidenceParams",
           "weighted_median"]


# ----------------------------------------------------------------------------------------------
# occlusion handling (two-view)
# ----------------------------------------------------------------------------------------------

def _check_disp(d, name):
    a = np.asarray(d)
    if a.ndim != 2:
        raise InvalidInputError(f"{name} must be a 2-D disparity map, got shape {a.shape}")
    if not np.issubdtype(a.dtype, np.number):
        raise InvalidInputError(f"{name} must be numeric, got dtype {a.dtype}")
    return a


def left_right_check(disp_left, disp_right, tol: float = 1.0) -> np.ndarray:
    """Left-right consistency: True where the left disparity is confirmed by the right one.

    Left pixel ``x`` with disparity ``d`` looks up the right map at ``x_r = round(x - d)``
    (Middlebury: ``x_right = x_left - d``; the right map stores, for right pixel ``x_r``, the
    disparity ``d_R`` with ``x_left = x_r + d_R``, both positive).

    Parameters
    ----------
    disp_left, disp_right : array_like, shape (H, W)
        Disparity maps of the two views (NaN allowed: never valid).
    tol : float
        Largest accepted ``|d_L - d_R(x_r)|``.

    Returns
    -------
    ndarray of bool, shape (H, W)
        True iff ``x_r`` is inside the image, both values are finite and they agree to ``tol``.

    Examples
    --------
    >>> import numpy as np
    >>> left_right_check(np.full((1, 4), 1.0), np.full((1, 4), 1.0)).tolist()
    [[False, True, True, True]]
    """
    dl = _check_disp(disp_left, "disp_left").astype(np.float64)
    dr = _check_disp(disp_right, "disp_right").astype(np.float64)
    if dl.shape != dr.shape:
        raise InvalidInputError(
            f"disp_left and disp_right must have the same shape, got {dl.shape} and {dr.shape}")
    tol = number(tol, "tol")
    H, W = dl.shape
    xs = np.arange(W)[None, :]
    with np.errstate(invalid="ignore"):
        xr = np.floor(xs - dl + 0.5)
    inside = np.isfinite(xr) & (xr >= 0) & (xr <= W - 1)
    xri = np.where(inside, xr, 0).astype(np.intp)
    drv = np.take_along_axis(dr, xri, axis=1)
    with np.errstate(invalid="ignore"):
        ok = inside & np.isfinite(drv) & (np.abs(dl - drv) <= tol)
    return ok


def left_occlusions(disp_right) -> np.ndarray:
    """Left pixels that no right pixel maps to: occluded in the right view.

    Right pixel ``x_r`` with disparity ``d_R`` sees left pixel ``round(x_r + d_R)``; a left
    pixel that none of its row's right pixels sees is hidden from the right camera (or
    outside its image).  Of the pixels that fail :func:`left_right_check`, these are the
    occlusions and the others the mismatches (Hirschmüller 2008, section 3.4).

    Parameters
    ----------
    disp_right : array_like, shape (H, W)
        The right view's disparity map (NaN allowed: that pixel sees nothing).

    Returns
    -------
    ndarray of bool, shape (H, W)

    References
    ----------
    .. [1] H. Hirschmüller, "Stereo processing by semiglobal matching and mutual
       information", IEEE TPAMI 30(2), 2008.

    Examples
    --------
    >>> import numpy as np
    >>> left_occlusions(np.array([[0.0, 0.0, 1.0, 1.0]])).tolist()   # x = 2 is seen by nobody
    [[False, False, True, False]]
    """
    dr = _check_disp(disp_right, "disp_right").astype(np.float64)
    H, W = dr.shape
    with np.errstate(invalid="ignore"):
        xl = np.floor(np.arange(W)[None, :] + dr + 0.5)
    ok = np.isfinite(xl) & (xl >= 0) & (xl <= W - 1)
    seen = np.zeros((H, W), dtype=bool)
    rows = np.broadcast_to(np.arange(H)[:, None], (H, W))
    seen[rows[ok], xl[ok].astype(np.intp)] = True
    return ~seen


def fill_occlusions(disp, valid) -> np.ndarray:
    """Fill invalid pixels from the background side (SPEC §4).

    Each invalid pixel takes ``min`` of the nearest valid disparity to its left and to its right
    on the same row (the lower disparity = the background); with a valid neighbour on one side
    only, that one.  Rows with no valid pixel get the minimum valid disparity of the whole map.
    No median filtering.

    Parameters
    ----------
    disp : array_like, shape (H, W)
        Disparity map.
    valid : array_like of bool, shape (H, W)
        Pixels to keep (e.g. :func:`left_right_check`); non-finite values count as invalid.

    Returns
    -------
    ndarray, shape (H, W)
        float32 (float64 when ``disp`` is float64), every pixel filled.

    Raises
    ------
    InvalidInputError
        No pixel is valid.

    Examples
    --------
    >>> import numpy as np
    >>> fill_occlusions(np.array([[5.0, 1.0, 7.0, 3.0]]),
    ...                 np.array([[False, True, False, True]])).tolist()
    [[1.0, 1.0, 1.0, 3.0]]
    """
    d = _check_disp(disp, "disp")
    out_dtype = np.float64 if d.dtype == np.float64 else np.float32
    d = d.astype(out_dtype)
    v = np.asarray(valid, dtype=bool)
    if v.shape != d.shape:
        raise InvalidInputError(f"valid must have shape {d.shape}, got {v.shape}")
    v = v & np.isfinite(d)
    if not v.any():
        raise InvalidInputError("fill_occlusions: no valid pixel to fill from")
    H, W = d.shape
    idx = np.broadcast_to(np.arange(W), (H, W))
    left_i = np.maximum.accumulate(np.where(v, idx, -1), axis=1)
    right_i = np.minimum.accumulate(np.where(v, idx, W)[:, ::-1], axis=1)[:, ::-1]
    left_v = np.where(left_i >= 0, np.take_along_axis(d, np.clip(left_i, 0, W - 1), axis=1), np.inf)
    right_v = np.where(right_i < W, np.take_along_axis(d, np.clip(right_i, 0, W - 1), axis=1),
                       np.inf)
    fill = np.minimum(left_v, right_v)
    fill = np.where(np.isfinite(fill), fill, d[v].min())
    return np.where(v, d, fill).astype(out_dtype)


def right_cost_from_left(cost_left, labels=None) -> np.ndarray:
    """Cost volume for the right view from the left one: ``C_R(x, d) = C_L(x + d, d)``.

    Integer disparities shift exactly; non-integer ones interpolate ``C_L`` linearly along x.
    Entries whose source ``x + d`` falls outside the image get that right pixel's worst valid
    cost (a right pixel with no valid label gets the worst cost of the volume).  WTA on the
    result gives the right disparity map for :func:`left_right_check`.

    Parameters
    ----------
    cost_left : array_like, shape (L, H, W)
        Finite left-referenced volume (left ``x`` vs right ``x - d``).
    labels : array_like, shape (L,), optional
        Disparities of the labels (default ``0..L-1``).

    Returns
    -------
    ndarray, float32, shape (L, H, W)

    Examples
    --------
    Label 1 reads the left cost one pixel to the right; the last right pixel has no left
    pixel at that label and gets its worst valid cost, 3:

    >>> left = np.arange(8.0).reshape(2, 1, 4)
    >>> left[1, 0].tolist(), right_cost_from_left(left)[1, 0].tolist()
    ([4.0, 5.0, 6.0, 7.0], [5.0, 6.0, 7.0, 3.0])
    """
    c = check_cost(cost_left, "cost_left")
    L, H, W = c.shape
    lv = check_labels(labels, L)
    out = np.empty_like(c)
    valid = np.zeros((L, W), dtype=bool)
    xs = np.arange(W, dtype=np.float64)
    for l in range(L):
        d = lv[l]
        if d == np.round(d):
            k = int(np.round(d))
            # out[:, x] = c[:, x + k] for 0 <= x + k < W
            lo, hi = max(0, -k), min(W, W - k)
            if lo < hi:
                out[l, :, lo:hi] = c[l, :, lo + k:hi + k]
                valid[l, lo:hi] = True
        else:
            x0, x1, t, valid[l] = coordinate_taps(xs + d, W)
            out[l] = (c[l][:, x0] * (1 - t) + c[l][:, x1] * t).astype(np.float32)
    return _fill_outside(out, valid, c)


def _fill_outside(out, valid, c):
    """Give ``out``'s entries outside ``valid`` (L, W) their right pixel's worst valid cost,
    label by label in place (no volume-sized temporary)."""
    worst = np.full(out.shape[1:], -np.inf, dtype=out.dtype)
    for l in range(out.shape[0]):
        cols = valid[l]
        worst[:, cols] = np.maximum(worst[:, cols], out[l][:, cols])
    worst = np.where(np.isfinite(worst), worst, c.max())
    for l in range(out.shape[0]):
        cols = ~valid[l]
        out[l][:, cols] = worst[:, cols]
    return out


# ----------------------------------------------------------------------------------------------
# sub-pixel refinement and confidence
# ----------------------------------------------------------------------------------------------

def subpixel_refine(cost, labels_map, labels=None) -> np.ndarray:
    """Sub-pixel disparity by a parabola through the cost at labels ``l-1, l, l+1``.

    Offset ``o = (c[l-1] - c[l+1]) / (2 (c[l-1] - 2 c[l] + c[l+1]))`` clamped to
    ``[-0.5, 0.5]``; disparity ``labels[l] + o * s``.  No refinement (``o = 0``) at the first
    and last label or where the parabola is not convex.

    Parameters
    ----------
    cost : array_like, shape (L, H, W)
        The volume whose minimum chose the labels (for SGM the aggregated volume,
        :attr:`OptimiseResult.volume`).
    labels_map : array_like of int, shape (H, W)
        Chosen label indices.
    labels : array_like, shape (L,), optional
        Evenly spaced label disparities (step ``s``, default ``0..L-1``).

    Returns
    -------
    ndarray, float32, shape (H, W)
        Disparity in the units of ``labels``: the chosen label's value plus the parabola's
        offset times the label step.

    Examples
    --------
    >>> import numpy as np
    >>> c = ((np.arange(5.0) - 2.25) ** 2)[:, None, None]
    >>> float(subpixel_refine(c, np.array([[2]]))[0, 0])
    2.25
    """
    c = check_cost(cost)
    L, H, W = c.shape
    f = check_label_map(labels_map, L, H, W, "labels_map")
    lv = check_labels(labels, L)
    if L > 1:
        steps = np.diff(lv)
        step = float(steps.mean())
        if step == 0 or np.max(np.abs(steps - step)) > 1e-6 * abs(step):
            raise InvalidInputError("subpixel_refine needs evenly spaced labels")
    else:
        step = 0.0
    base = lv[f]
    if L < 3:
        return base.astype(np.float32)
    inner = (f > 0) & (f < L - 1)
    fm = np.clip(f - 1, 0, L - 1)
    fp = np.clip(f + 1, 0, L - 1)
    c0 = gather(c, fm)
    c1 = gather(c, f)
    c2 = gather(c, fp)
    denom = c0 - 2.0 * c1 + c2
    ok = inner & (denom > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.where(ok, (c0 - c2) / (2.0 * np.where(ok, denom, 1.0)), 0.0)
    off = np.clip(off, -0.5, 0.5)
    return (base + off * step).astype(np.float32)


def confidence(cost, labels_map=None, *, floor: float = 0.0) -> np.ndarray:
    """Cost-margin confidence in [0, 1].

    ``floor + (1 - floor) m``, ``m = (c2 - c(l)) / (max_l c - min_l c)`` clipped to [0, 1],
    where ``l`` is the chosen label and ``c2`` the lowest cost among labels more than one step
    away from ``l`` (so a broad minimum is not penalised).  ``m`` is 0 where a distant label is
    as good as the chosen one, and 1 when the chosen label is the minimum and everything away
    from it is the maximum.  A flat cost curve (no data) gives 0 whatever the floor.

    ``m`` is 0 on a large share of the pixels that a regulariser decides right: a repeated
    texture or a weak one gives some distant label as low a cost, or the regulariser overrides
    the pixel's own minimum.  Callers that set the confidence to 0 where a check fails (the
    left-right check, an unseen pixel) pass a ``floor`` so that the pixels which pass rank above
    those which do not (BENCHMARKS.md, fortieth session).

    Parameters
    ----------
    cost : array_like, shape (L, H, W)
        The volume that chose the labels.
    labels_map : array_like of int, shape (H, W), optional
        Chosen label indices (default: WTA of ``cost``).
    floor : float
        The confidence of a chosen label whose margin is 0, in [0, 1) (default 0).

    Returns
    -------
    ndarray, float32, shape (H, W)
        The cost margin of each pixel's label, ``floor`` (ambiguous) to 1 (unique).

    Examples
    --------
    >>> import numpy as np
    >>> c = np.array([[[0.0]], [[1.0]], [[0.0]]], np.float32)   # labels 0 and 2 tie
    >>> lab = np.zeros((1, 1), int)
    >>> float(confidence(c, lab)[0, 0]), round(float(confidence(c, lab, floor=0.1)[0, 0]), 6)
    (0.0, 0.1)
    """
    c = check_cost(cost)
    L, H, W = c.shape
    f = np.argmin(c, axis=0) if labels_map is None else check_label_map(labels_map, L, H, W,
                                                                          "labels_map")
    floor = number(floor, "floor")
    if floor >= 1.0:
        raise InvalidInputError(f"floor must be below 1, got {floor!r}")
    if L < 2:
        return np.zeros((H, W), dtype=np.float32)
    c2 = np.full((H, W), np.inf, np.float32)
    for k in range(L):  # label by label: no temporary volume
        np.minimum(c2, np.where(np.abs(k - f) > 1, c[k], np.float32(np.inf)), out=c2)
    c2 = c2.astype(np.float64)
    cf = gather(c, f)
    rng = c.max(axis=0).astype(np.float64) - c.min(axis=0)
    c2 = np.where(np.isfinite(c2), c2, c.max(axis=0))  # L <= 3: no far label
    with np.errstate(divide="ignore", invalid="ignore"):
        conf = np.where(rng > 0, (c2 - cf) / np.where(rng > 0, rng, 1.0), 0.0)
    conf = np.clip(conf, 0.0, 1.0)
    if floor > 0:
        conf = np.where(rng > 0, floor + (1.0 - floor) * conf, 0.0)
    return conf.astype(np.float32)


def edge_confidence(disparity, *, width: float = 4.0, jump: float = 0.5) -> np.ndarray:
    """How far each pixel is from a depth edge of ``disparity``, as a weight in [0, 1].

    ``min(1, dist / width)``, ``dist`` the Euclidean distance (px) to the nearest pixel whose
    3 x 3 neighbourhood spans more than ``jump`` (disparity units): 0 on an estimated depth
    edge, 1 from ``width`` px away.  Window costs spread the foreground over the background
    there and a post-filter can take the foreground's edge to the background, so that is where
    a disparity map's errors gather (BENCHMARKS.md, thirty-ninth session); the cost margin of
    :func:`confidence` does not see it.  Non-finite disparities count as depth edges (and as
    0 in their neighbours' spans).

    Parameters
    ----------
    disparity : array_like, shape (H, W)
    width : float
        Distance (px) from which a pixel is not discounted; 0 returns ones.
    jump : float
        The smallest span of a 3 x 3 neighbourhood that counts as a depth edge (> 0).

    Returns
    -------
    ndarray, float32, shape (H, W)

    Examples
    --------
    >>> import numpy as np
    >>> d = np.zeros((1, 7)); d[0, 4:] = 2.0              # a step between columns 3 and 4
    >>> edge_confidence(d, width=2.0).round(2).tolist()
    [[1.0, 1.0, 0.5, 0.0, 0.0, 0.5, 1.0]]
    """
    from scipy import ndimage as ndi

    d = real_array(disparity, "disparity")
    if d.ndim != 2:
        raise InvalidInputError(f"disparity must be (H, W), got shape {d.shape}")
    width = number(width, "width")
    jump = number(jump, "jump", positive=True)
    if width == 0.0:
        return np.ones(d.shape, np.float32)
    bad = ~np.isfinite(d)
    f = np.where(bad, 0.0, d)
    span = ndi.maximum_filter(f, size=3, mode="nearest") - ndi.minimum_filter(f, size=3,
                                                                               mode="nearest")
    edge = (span > jump) | bad
    if not edge.any():
        return np.ones(d.shape, np.float32)
    dist = ndi.distance_transform_edt(~edge)
    return np.minimum(1.0, dist / width).astype(np.float32)


def label_saving(volume, labels, disparity, proposal, *, trusted=None) -> np.ndarray:
    """What a cost volume saves per pixel at ``proposal``'s nearest label against
    ``disparity``'s, in units of the median of the volume's range (``max - min`` over labels)
    over the ``trusted`` pixels; the ``support`` of :func:`thin_foreground` and
    :func:`enclosed_background`.

    Parameters
    ----------
    volume : array_like, shape (L, H, W)
        Finite costs, lower is better (a data term or a unary).
    labels : array_like, shape (L,)
        The disparity of each label, evenly spaced and increasing.
    disparity, proposal : array_like, shape (H, W)
        Finite maps; each pixel's value is read at its nearest label (clipped to the range).
    trusted : array_like of bool, shape (H, W), optional
        The pixels whose data count, on which the typical range is measured (every pixel
        when None).

    Returns
    -------
    ndarray, float64, shape (H, W)
        Positive where the volume prefers ``proposal``; zeros where no counted pixel has a
        range (the volume then vouches for nothing).

    Examples
    --------
    >>> import numpy as np
    >>> volume = np.array([[[0.0]], [[1.0]], [[2.0]]])   # three labels, one pixel
    >>> label_saving(volume, [0.0, 1.0, 2.0], [[2.0]], [[0.0]]).tolist()
    [[1.0]]
    """
    U = check_cost(volume, "volume", dtype=None)
    L, H, W = U.shape
    lab = check_labels(labels, L)
    d = array(disparity, "disparity", (H, W), finite=True, of=" (the volume's)")
    p = array(proposal, "proposal", (H, W), finite=True, of=" (the volume's)")
    step = float(lab[1] - lab[0]) if L > 1 else 1.0
    if not step > 0:
        raise InvalidInputError(f"labels must increase, got {lab[0]:g} then {lab[1]:g}")

    def at(m):
        i = np.clip(np.rint((m - lab[0]) / step), 0, L - 1).astype(np.intp)
        return np.take_along_axis(U, i[None], axis=0)[0].astype(np.float64)

    spread = U.max(axis=0) - U.min(axis=0)
    counted = spread if trusted is None else spread[bool_mask(trusted, "trusted", (H, W))]
    scale = float(np.median(counted)) if counted.size else 0.0
    if not scale > 0:
        return np.zeros(spread.shape)
    return (at(d) - at(p)) / scale


def thin_foreground(disparity, proposal, *, jump: float = 1.0, touch: float = 0.25,
                    min_size: int = 10, support=None, min_support: float = 0.0,
                    trusted=None, coherent: float = 0.0) -> np.ndarray:
    """The thin foreground that ``proposal`` finds and ``disparity`` lost, as a mask.

    A regulariser that charges for every px of an outline gives a thin object (a rod, a wire,
    a stem) to the background behind it when few pixels vouch for it: the outline costs more
    than the object's evidence.  A second estimate that charges less (SGM against graph cuts)
    keeps it, but also fattens the foreground elsewhere.  The two cases differ in where the
    component lies against ``disparity``'s own surface at the component's depth: a lost thin
    object meets it at most at its ends, a fattened edge along a whole side.

    A pixel is taken when it belongs to an 8-connected component of at least ``min_size`` px
    where ``proposal`` is nearer than ``disparity`` by more than ``jump``, and fewer than
    ``touch`` of the component's outline (the 8-neighbours outside it) have a ``disparity``
    within ``jump`` of the component's median ``proposal``.  The outline beyond the image
    counts as touching: a strip along the border is more likely the proposal's own border
    artefact (where few views see a pixel) than an object, and a rod that leaves the image
    across the border loses only its width there.  With ``support``, a component is taken
    only where the mean of ``support`` over it is above ``min_support``: the data must
    vouch for the proposal, as they do for an object that only the outline's cost removed.
    With ``trusted``, a component is taken only where more than half of its pixels are
    trusted: a proposal spread over pixels whose data do not count is no object.  With
    ``coherent`` above 0, a component is taken only where at least that share of its pixels
    have a ``proposal`` within ``jump`` of its median: an object shows one surface, and a
    proposal scattered over many depths is the proposal's own noise (weak or repeated
    texture).

    Parameters
    ----------
    disparity, proposal : array_like, shape (H, W)
        Finite disparity maps, larger = nearer: the estimate and the second opinion.
    jump : float
        Disparity units (> 0): how much nearer ``proposal`` must be, and how close to the
        component's depth an outline pixel must be to count as touching it.
    touch : float
        The share of the outline in (0, 1] from which a component counts as attached.
    min_size : int
        Smaller components (>= 1 px) are left alone: the proposal's own noise.
    support : array_like, shape (H, W), optional
        Finite; how much the data prefer ``proposal`` to ``disparity`` at each pixel
        (:func:`hyperlf.hlf.thin_objects`: the unary's saving, in units of its typical range).
    min_support : float
        What a component's mean ``support`` must exceed (ignored without ``support``).
    trusted : array_like of bool, shape (H, W), optional
        The pixels whose data count (:func:`hyperlf.hlf.thin_objects`: a texture weight of
        at least 0.5; :func:`hyperlf.twoview.open_holes`: the proposal's own left-right
        check).
    coherent : float
        In [0, 1]: the share of a component's pixels that must lie within ``jump`` of its
        median ``proposal`` (0: no such test).

    Returns
    -------
    ndarray, bool, shape (H, W)

    See Also
    --------
    hyperlf.hlf.thin_objects : the depth stage that uses it.

    Examples
    --------
    A rod 2 px wide, 3 px nearer than the wall, that only the proposal kept; and a
    foreground square that the proposal widened by 2 px:

    >>> import numpy as np
    >>> d = np.zeros((20, 30)); d[:, 20:] = 3.0             # the square, from column 20
    >>> p = d.copy(); p[2:18, 5:7] = 3.0; p[:, 18:20] = 3.0  # the rod; the widened edge
    >>> taken = thin_foreground(d, p)
    >>> bool(taken[2:18, 5:7].all()), bool(taken[:, 18:20].any())
    (True, False)
    """
    return _detached(disparity, proposal, 1.0, jump=jump, touch=touch, min_size=min_size,
                     support=support, min_support=min_support, trusted=trusted,
                     coherent=coherent)


def enclosed_background(disparity, proposal, *, jump: float = 1.0, touch: float = 0.25,
                        min_size: int = 10, support=None, min_support: float = 0.0,
                        trusted=None, coherent: float = 0.0) -> np.ndarray:
    """The background that ``proposal`` sees through a hole and ``disparity`` filled with
    the foreground around it, as a mask.

    The counterpart of :func:`thin_foreground`.  A regulariser that charges for every px
    of an outline also closes a hole (the inside of a ring, a gap between a rod and a box)
    whose few pixels of background vouch more weakly than its outline costs: the
    foreground around it flows in.  The rule is :func:`thin_foreground`'s with the sides
    swapped: a pixel is taken when it belongs to an 8-connected component of at least
    ``min_size`` px where ``proposal`` is *farther* than ``disparity`` by more than
    ``jump``, and fewer than ``touch`` of the component's outline have a ``disparity``
    within ``jump`` of the component's median ``proposal``.  A hole is enclosed by the
    foreground; a foreground edge that ``disparity`` fattened and ``proposal`` did not lies
    along the background at the component's depth, and is left alone.  ``support`` and
    ``trusted`` count as there.  Two more guards hold for holes: a component that reaches
    the image's border is left (nothing shows that the foreground closes around it beyond
    the border), and so is one at whose median ``proposal`` fewer than ``min_size`` pixels
    of ``disparity`` lie (within ``jump``): the background seen through a hole is a surface
    that ``disparity`` holds elsewhere.  Where few views see a pixel the proposal can go
    astray to depths no surface holds, and the unary, whose labels no view sees there,
    does not contradict it (the top rows of a rig whose other views do not see them at their
    true depth, BENCHMARKS.md, fifty-ninth session).

    Parameters
    ----------
    disparity, proposal, jump, touch, min_size, support, min_support, trusted, coherent
        As for :func:`thin_foreground` (``jump``: how much farther ``proposal`` must be).

    Returns
    -------
    ndarray, bool, shape (H, W)

    See Also
    --------
    thin_foreground : the thin objects themselves.
    hyperlf.hlf.thin_objects : the depth stage that uses both.
    hyperlf.twoview.open_holes : two-view stereo's step that uses it.

    Examples
    --------
    A wall at 0 behind a ring at 3 whose hole ``disparity`` filled; and a square whose
    edge ``disparity`` widened by 2 px onto the wall:

    >>> import numpy as np
    >>> p = np.zeros((20, 40)); p[2:18, 2:18] = 3.0; p[6:14, 6:14] = 0.0   # ring, hole
    >>> p[4:16, 26:36] = 3.0                                               # the square
    >>> d = p.copy(); d[6:14, 6:14] = 3.0; d[4:16, 24:26] = 3.0
    >>> taken = enclosed_background(d, p)
    >>> bool(taken[6:14, 6:14].all()), bool(taken[:, 20:].any())
    (True, False)
    """
    return _detached(disparity, proposal, -1.0, jump=jump, touch=touch, min_size=min_size,
                     support=support, min_support=min_support, trusted=trusted,
                     coherent=coherent)


def _detached(disparity, proposal, side: float, *, jump, touch, min_size, support,
              min_support, trusted, coherent) -> np.ndarray:
    """:func:`thin_foreground` (``side`` 1: ``proposal`` nearer) and
    :func:`enclosed_background` (``side`` -1: farther)."""
    from scipy import ndimage as ndi

    d = array(disparity, "disparity", ndim=2, finite=True).astype(np.float64)
    p = array(proposal, "proposal", d.shape, finite=True, of=" (disparity's)")
    p = p.astype(np.float64)  # integer maps too: no wrap-around in p - d
    jump = number(jump, "jump", positive=True)
    touch = number(touch, "touch", positive=True, at_most=1)
    min_size = integer(min_size, "min_size", minimum=1)
    min_support = number(min_support, "min_support")
    coherent = number(coherent, "coherent", at_most=1)
    if support is not None:
        support = np.pad(array(support, "support", d.shape, finite=True,
                               of=" (disparity's)").astype(np.float64), 1)
    if trusted is not None:
        trusted = np.pad(bool_mask(trusted, "trusted", d.shape), 1)
    eight = np.ones((3, 3), bool)
    # the estimate's depths, sorted: a hole shows one of its surfaces
    depths = np.sort(d, axis=None) if side < 0 else None
    components, n = ndi.label(np.pad(side * (p - d) > jump, 1), structure=eight)
    sizes = np.bincount(components.ravel(), minlength=n + 1)
    d = np.pad(d, 1, constant_values=np.nan)  # beyond the image: counts as touching
    p = np.pad(p, 1)
    taken = np.zeros(d.shape, bool)
    for i, box in enumerate(ndi.find_objects(components), start=1):
        if sizes[i] < min_size:
            continue
        box = tuple(slice(s.start - 1, s.stop + 1) for s in box)
        own = components[box] == i
        if support is not None and not support[box][own].mean() > min_support:
            continue
        if trusted is not None and not 2 * np.count_nonzero(trusted[box][own]) > sizes[i]:
            continue
        level = np.median(p[box][own])
        if coherent > 0 and np.mean(np.abs(p[box][own] - level) <= jump) < coherent:
            continue
        outline = d[box][ndi.binary_dilation(own, eight) & ~own]
        beyond = np.isnan(outline)
        if side < 0 and (beyond.any() or _held(depths, level, jump) < min_size):
            continue  # a hole is enclosed within the image, and shows a surface held
        if np.mean(beyond | (np.abs(outline - level) <= jump)) < touch:
            taken[box] |= own
    return taken[1:-1, 1:-1]


def _held(depths: np.ndarray, level: float, jump: float) -> int:
    """How many of the sorted ``depths`` lie within ``jump`` of ``level``."""
    lo = np.searchsorted(depths, level - jump, side="left")
    hi = np.searchsorted(depths, level + jump, side="right")
    return int(hi - lo)


@dataclass(frozen=True)
class ConfidenceParams:
    """Constants of a disparity map's confidence: ``confidence(cost, labels, floor=floor)``
    times ``edge_confidence(disparity, width=edge_px, jump=edge_jump)``, 0 where the caller's
    checks fail.

    The defaults are two-view stereo's (:func:`hyperlf.twoview.stereo`; disparities in px),
    chosen on Venus and then the procedural pairs (BENCHMARKS.md, fortieth session).  The
    light field's are fields of :class:`hyperlf.hlf.DepthParams` (``confidence_floor``,
    ``confidence_edge_px``, ``confidence_edge_jump``), in its own disparity units.

    Attributes
    ----------
    floor : float
        :func:`confidence`'s ``floor``, in [0, 1).
    edge_px : float
        :func:`edge_confidence`'s ``width``, px (0: no discount at depth edges).
    edge_jump : float
        :func:`edge_confidence`'s ``jump``, disparity units (> 0).
    """

    name: ClassVar[str] = "confidence"
    floor: float = 0.1
    edge_px: float = 8.0
    edge_jump: float = 1.5

    def __post_init__(self):
        check_fields(self, {"floor": rule(number, below=1), "edge_px": number,
                            "edge_jump": rule(number, positive=True)}, f"{self.name} ")


@dataclass(frozen=True)
class HoleParams:
    """Constants of two-view stereo's holes step (:func:`hyperlf.twoview.open_holes`), on
    by default: graph cuts solved again with ``weight_share`` of their smoothness weight,
    and the components that this second answer puts farther and that
    :func:`enclosed_background` finds enclosed by the first answer's foreground taken from
    it.

    ``jump``, ``touch``, ``min_size`` and ``min_support`` are the light field's
    (:class:`hyperlf.hlf.DepthParams`: ``thin_jump``, ``thin_hole_touch``,
    ``thin_min_size``, ``thin_min_support``); the share, the coherence and the left-right
    guard were measured on Venus and the procedural pairs (BENCHMARKS.md, sixty-first
    session), and the step made the default on them and on a third set of weakly textured
    foregrounds (sixty-fifth session, where the rule is given).

    Attributes
    ----------
    enabled : bool
        Run the step (graph cuts only; on by default).
    weight_share : float
        The second solve's smoothness weight as a share of graph cuts', in (0, 1).
    jump, touch, min_size, min_support, coherent
        :func:`enclosed_background`'s (``jump`` in px; ``min_support`` against
        :func:`label_saving` of the data term).
    consistent : bool
        With both views' volumes: a component is opened only where more than half of its
        pixels pass the left-right check (1 px) between the two second answers.
    """

    name: ClassVar[str] = "holes"
    enabled: bool = True
    weight_share: float = 0.5
    jump: float = 1.0
    touch: float = 0.7
    min_size: int = 10
    min_support: float = 0.05
    coherent: float = 0.3
    consistent: bool = True

    def __post_init__(self):
        check_fields(self, {"enabled": flag, "consistent": flag,
                            "weight_share": rule(number, positive=True, below=1),
                            "jump": rule(number, positive=True),
                            "touch": rule(number, positive=True, at_most=1),
                            "min_size": rule(integer, minimum=1),
                            "min_support": number,
                            "coherent": rule(number, at_most=1)}, f"{self.name} ")


# ----------------------------------------------------------------------------------------------
# edge-aware post-filter
# ----------------------------------------------------------------------------------------------

#: The smallest guide sigma of :func:`weighted_median`: far below any difference of a guide
#: scaled to its maximum, far above where its square underflows.
MIN_WMF_SIGMA = 1e-6


def _wmf_args(disp, guide, radius, sigma):
    d = real_array(disp, "disparity")
    if d.ndim != 2 or not np.all(np.isfinite(d)):
        raise InvalidInputError(f"disparity must be a finite (H, W) map, got shape {d.shape}")
    g = real_array(guide, "guide")
    if g.shape != d.shape or not np.all(np.isfinite(g)):
        raise InvalidInputError(f"guide must be a finite image of shape {d.shape}, got {g.shape}")
    radius = integer(radius, "radius")
    if radius > max(d.shape):
        raise InvalidInputError(f"radius {radius} is larger than the {d.shape[1]} x "
                                f"{d.shape[0]} px image; use at most {max(d.shape)}")
    sigma = number(sigma, "sigma", positive=True)
    if sigma < MIN_WMF_SIGMA:  # its square would underflow in the weights
        raise InvalidInputError(f"sigma must be at least {MIN_WMF_SIGMA:g} (the guide is scaled "
                                f"to its maximum), got {sigma:g}")
    m = float(np.mean(np.abs(g)))
    return d, (g / m if m > 0 else g), int(radius), float(sigma)


def _weighted_median_numpy(d, g, r, sigma):
    H, W = d.shape
    dp = np.pad(d, r, mode="edge")
    gp = np.pad(g, r, mode="edge")
    vals, wts = [], []
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            vals.append(dp[r + dy:r + dy + H, r + dx:r + dx + W])
            gq = gp[r + dy:r + dy + H, r + dx:r + dx + W]
            wts.append(np.exp(-(g - gq) ** 2 / (2.0 * sigma * sigma)))
    v = np.stack(vals)
    w = np.stack(wts)
    order = np.argsort(v, axis=0, kind="stable")
    v = np.take_along_axis(v, order, axis=0)
    cw = np.cumsum(np.take_along_axis(w, order, axis=0), axis=0)
    k = np.argmax(cw >= 0.5 * cw[-1][None], axis=0)
    return np.take_along_axis(v, k[None], axis=0)[0]


def weighted_median(disparity, guide, radius: int = 7, sigma: float = 0.1,
                    impl: str = "auto", *, mask=None) -> np.ndarray:
    """Guided weighted median of a disparity map: an edge-aware post-filter.

    It moves depth edges onto image edges (window-based costs "fatten" foreground objects by
    about half a window across occlusion boundaries).  Each pixel takes the weighted median of
    the disparities in its ``(2 radius + 1)^2`` window, weights
    ``exp(-(g_p - g_q)^2 / (2 sigma^2))`` from the guide divided by its mean absolute value
    (borders replicated).  The weighted median is the smallest window value whose cumulative
    weight reaches half the total.  A median keeps planar (linear) disparity ramps where the
    weights are symmetric and removes isolated outliers.  It corrects a fattened edge of up to
    about ``radius / 2`` px: beyond that the wrong disparity holds the majority of the pixels
    on the edge's own side.

    Parameters
    ----------
    disparity : array_like, shape (H, W)
        Finite disparity map, px.
    guide : array_like, shape (H, W)
        Image of the same view (any positive scale).
    radius : int
        Window radius in px (0: no-op).
    sigma : float
        Guide similarity scale, relative to the guide's mean.
    impl : {"auto", "numba", "numpy"}
        ``"numpy"`` is the reference (memory ~ 16 (2r+1)^2 H W bytes); ``"auto"`` is numba.
    mask : array_like of bool, shape (H, W), optional
        The pixels to filter (default: all); the others keep their disparity.  Their
        neighbours' values still enter the medians.  The numba version computes only these.

    Returns
    -------
    ndarray, float32, shape (H, W)
        The filtered disparity, px; ``disparity`` itself when ``radius`` is 0.

    Examples
    --------
    >>> import numpy as np
    >>> d = np.zeros((5, 5)); d[2, 2] = 9.0          # an isolated outlier
    >>> float(weighted_median(d, np.ones((5, 5)), radius=1, impl="numpy")[2, 2])
    0.0
    """
    d, g, r, sigma = _wmf_args(disparity, guide, radius, sigma)
    choice(impl, "impl", ("auto", "numpy", "numba"))
    m = np.ones(d.shape, bool) if mask is None else \
        np.ascontiguousarray(bool_mask(mask, "mask", d.shape, of="the disparity"))
    if r == 0:
        return d.astype(np.float32)
    if impl == "numpy":
        return np.where(m, _weighted_median_numpy(d, g, r, sigma), d).astype(np.float32)
    from . import _kernels

    out = np.empty(d.shape, np.float64)
    _kernels.weighted_median(d, g, r, sigma, m, out)
    return out.astype(np.float32)
