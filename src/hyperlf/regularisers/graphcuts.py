"""Graph cuts: alpha-expansion on the 4-connected grid (PyMaxflow), plain and coarse to fine.

The MRF energy minimised by :func:`graphcut` (and evaluated by :func:`mrf_energy`) is::

    E(f) = sum_p cost[f_p, p] + sum_{(p,q) 4-neighbours} w_pq * V(f_p, f_q)

with ``V = min(|labels[a] - labels[b]|, T)`` (truncated linear, disparity units) or
``V = [a != b]`` (Potts), and ``w_pq = weight * (guide edge factor) * (explicit edge weight)``.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..errors import InvalidInputError
from ..imageops import block_reduce
from .._options import choice, flag, integer, number, real_array
from ._checks import check_cost, check_guide, check_label_map, check_labels, gather

__all__ = ["edge_weights_from_guide", "mrf_energy", "graphcut", "candidate_labels",
           "graphcut_multiscale", "GRAPHCUT_SMOOTHNESS"]

#: Smoothness terms :func:`graphcut` accepts (both metrics, so every move is submodular).
GRAPHCUT_SMOOTHNESS = ("truncated_linear", "potts")

def edge_weights_from_guide(guide, edge_sigma: float | None = None):
    """Contrast-sensitive edge factors ``exp(-||I_p - I_q||^2 / (2 edge_sigma^2))``.

    Parameters
    ----------
    guide : array_like, shape (H, W) or (H, W, K)
        Guide image (Euclidean norm over channels).
    edge_sigma : float, optional
        Default: the root-mean-square 4-neighbour difference of the guide (1 if the guide is
        constant), so the default is invariant to the guide's scale.

    Returns
    -------
    wx : ndarray, shape (H, W-1)
        Factors of the pairs ``(y, x)-(y, x+1)``, in (0, 1].
    wy : ndarray, shape (H-1, W)
        Factors of the pairs ``(y, x)-(y+1, x)``.

    Examples
    --------
    A step of 1 in the guide with ``edge_sigma`` 0.5 weighs ``exp(-1 / 0.5)``:

    >>> wx, wy = edge_weights_from_guide(np.array([[0.0, 0.0, 1.0]]), edge_sigma=0.5)
    >>> wx.round(4).tolist(), wy.shape
    ([[1.0, 0.1353]], (0, 3))
    """
    g0 = np.asarray(guide)
    if g0.ndim not in (2, 3):
        raise InvalidInputError(f"guide must be (H, W) or (H, W, K), got shape {g0.shape}")
    H, W = g0.shape[:2]
    g = check_guide(g0, H, W)
    dx2 = ((g[:, 1:] - g[:, :-1]) ** 2).sum(axis=-1)
    dy2 = ((g[1:, :] - g[:-1, :]) ** 2).sum(axis=-1)
    if edge_sigma is None:
        n = dx2.size + dy2.size
        ms = (dx2.sum() + dy2.sum()) / n if n else 0.0
        edge_sigma = float(np.sqrt(ms)) if ms > 0 else 1.0
    else:
        # at least 1e-150, so that 2 edge_sigma^2 is not 0 in float64
        edge_sigma = number(edge_sigma, "edge_sigma", positive=True, at_least=1e-150)
    with np.errstate(over="ignore"):  # a huge sigma: no edge weighs less (s2 = inf)
        s2 = 2.0 * np.float64(edge_sigma) ** 2
    return np.exp(-dx2 / s2), np.exp(-dy2 / s2)


def _check_edge_weights(edge_weights, shape_x, shape_y):
    try:
        ex, ey = edge_weights
    except (TypeError, ValueError):
        raise InvalidInputError(
            "edge_weights must be a pair (wx of shape (H, W-1), wy of shape (H-1, W))") from None
    ex, ey = real_array(ex, "edge_weights' wx"), real_array(ey, "edge_weights' wy")
    if ex.shape != shape_x or ey.shape != shape_y:
        raise InvalidInputError(
            f"edge_weights must have shapes {shape_x} and {shape_y}, got {ex.shape} and {ey.shape}")
    if not (np.all(np.isfinite(ex)) and np.all(np.isfinite(ey))) or ex.min(initial=0) < 0 \
            or ey.min(initial=0) < 0:
        raise InvalidInputError("edge_weights must be finite and >= 0")
    return ex, ey


def _pair_weights(H, W, weight, guide, edge_sigma, edge_weights):
    """Final (wx, wy) = weight * guide factors * explicit edge weights (float64)."""
    weight = number(weight, "weight")
    wx = np.full((H, W - 1), weight, dtype=np.float64)
    wy = np.full((H - 1, W), weight, dtype=np.float64)
    if guide is not None:
        if np.shape(guide)[:2] != (H, W):
            raise InvalidInputError(
                f"guide must have spatial shape {(H, W)}, got {np.shape(guide)}")
        gx, gy = edge_weights_from_guide(guide, edge_sigma)
        wx *= gx
        wy *= gy
    if edge_weights is not None:
        ex, ey = _check_edge_weights(edge_weights, wx.shape, wy.shape)
        wx *= ex
        wy *= ey
    return wx, wy


def _smoothness_matrix(smoothness, L, labels_values, truncation) -> np.ndarray:
    choice(smoothness, "smoothness", GRAPHCUT_SMOOTHNESS)
    if smoothness == "potts":
        return 1.0 - np.eye(L)
    if smoothness == "truncated_linear":
        lv = check_labels(labels_values, L)
        V = np.abs(lv[:, None] - lv[None, :])
        if truncation is not None:
            T = number(truncation, "truncation")
            V = np.minimum(V, T)
        return V
    raise InvalidInputError(
        f"smoothness must be 'truncated_linear' or 'potts', got {smoothness!r}")


def _energy(f, unary_f, Vm, wx, wy) -> float:
    e = float(unary_f.sum(dtype=np.float64))
    if wx.size:
        e += float((wx * Vm[f[:, :-1], f[:, 1:]]).sum())
    if wy.size:
        e += float((wy * Vm[f[:-1, :], f[1:, :]]).sum())
    return e


def mrf_energy(labels, cost, smoothness: str = "truncated_linear", weight: float = 1.0,
               truncation: float | None = None, guide=None, edge_sigma: float | None = None,
               edge_weights=None, labels_values=None) -> float:
    """Energy of a label map under the MRF of :func:`graphcut` (module docstring).

    Parameters
    ----------
    labels : array_like of int, shape (H, W)
        Label-index map.
    cost : array_like, shape (L, H, W)
        Finite cost volume.
    labels_values : array_like, shape (L,), optional
        Disparities of the labels (default ``0..L-1``), used by the truncated-linear term.
    smoothness, weight, truncation, guide, edge_sigma, edge_weights
        As in :func:`graphcut`.

    Returns
    -------
    float
        The energy, computed in float64.

    Examples
    --------
    With no data cost, labels 0, 0, 2 in a row pay their one jump of 2, or 1 when it is
    truncated there:

    >>> labels, cost = np.array([[0, 0, 2]]), np.zeros((3, 1, 3))
    >>> unit = (np.ones((1, 2)), np.ones((0, 3)))
    >>> mrf_energy(labels, cost, edge_weights=unit), mrf_energy(labels, cost, truncation=1.0,
    ...                                                        edge_weights=unit)
    (2.0, 1.0)
    """
    c = check_cost(cost)
    L, H, W = c.shape
    f = check_label_map(labels, L, H, W, "labels")
    Vm = _smoothness_matrix(smoothness, L, labels_values, truncation)
    wx, wy = _pair_weights(H, W, weight, guide, edge_sigma, edge_weights)
    return _energy(f, gather(c, f), Vm, wx, wy)


def candidate_labels(volume, k: int, spread: int = 1) -> np.ndarray:
    """Each pixel's ``k`` best labels, widened by ``spread`` labels on each side.

    Parameters
    ----------
    volume : array_like, shape (L, H, W)
        Any cost-like volume, lower is better; an aggregated one (:func:`sgm`) ranks labels
        far better than the raw data term in weakly textured areas.
    k : int
        Labels kept per pixel (``k >= L`` allows every label).
    spread : int
        Widening in labels, so that a slanted surface may move one step from its proposal.

    Returns
    -------
    ndarray of bool, shape (L, H, W)
        A mask for :func:`graphcut`'s ``candidates``.

    Examples
    --------
    The best label (1) widened by one on each side:

    >>> volume = np.array([3.0, 1.0, 2.0, 5.0]).reshape(4, 1, 1)
    >>> candidate_labels(volume, 1, spread=1)[:, 0, 0].tolist()
    [True, True, True, False]
    """
    c = check_cost(volume, "volume")
    L = c.shape[0]
    k, spread = integer(k, "k", 1), integer(spread, "spread", maximum=c.shape[0])
    if k >= L:
        return np.ones(c.shape, dtype=bool)
    top = np.argpartition(c, k - 1, axis=0)[:k]
    mask = np.zeros(c.shape, dtype=bool)
    np.put_along_axis(mask, top, True, axis=0)
    if spread:
        wide = mask.copy()
        for s_ in range(1, spread + 1):
            wide[s_:] |= mask[:-s_]
            wide[:-s_] |= mask[s_:]
        mask = wide
    return mask


# ----------------------------------------------------------------------------------------------
# alpha-expansion
# ----------------------------------------------------------------------------------------------

_RIGHT = np.array([[0, 0, 0], [0, 0, 1], [0, 0, 0]])
_DOWN = np.array([[0, 0, 0], [0, 0, 0], [0, 1, 0]])


def _move_terms(c, alpha, f, unary_f, Vm, wx, wy, capx, capy):
    """The expansion move for ``alpha`` as if every pixel were a variable (graphcut's Notes).

    Returns ``du`` = cost(switch) - cost(stay) per pixel; writes the pairwise capacities of the
    right and down pairs into ``capx`` and ``capy``.  The numba kernel
    :func:`hyperlf.regularisers._kernels.expansion_terms`; :func:`_move_terms_numpy` is its
    reference, bit for bit.
    """
    from . import _kernels

    du = np.empty(f.shape, dtype=np.float64)
    _kernels.expansion_terms(c[alpha], int(alpha), f, unary_f, Vm, wx, wy, du, capx, capy)
    return du


def _move_terms_numpy(c, alpha, f, unary_f, Vm, wx, wy, capx, capy):
    """The numpy reference of :func:`_move_terms`."""
    H, W = f.shape
    u1 = c[alpha].astype(np.float64)       # cost of x_p = 1 (take alpha)
    du = u1 - unary_f                        # cost(1) - cost(0)
    va = Vm[:, alpha]
    if W > 1:
        fp, fq = f[:, :-1], f[:, 1:]
        A = wx * Vm[fp, fq]
        B = wx * va[fp]
        Cq = wx * va[fq]
        du[:, :-1] += Cq - A
        du[:, 1:] -= Cq
        capx[:, :-1] = np.maximum(B + Cq - A, 0.0)
    if H > 1:
        fp, fq = f[:-1, :], f[1:, :]
        A = wy * Vm[fp, fq]
        B = wy * va[fp]
        Cq = wy * va[fq]
        du[:-1, :] += Cq - A
        du[1:, :] -= Cq
        capy[:-1, :] = np.maximum(B + Cq - A, 0.0)
    return du


def _full_move(g, du, capx, capy) -> np.ndarray:
    """Solve one expansion move over every pixel; returns the boolean sink-segment map."""
    H, W = du.shape
    nodes = g.add_grid_nodes((H, W))
    if W > 1:
        g.add_grid_edges(nodes, weights=capx, structure=_RIGHT, symmetric=False)
    if H > 1:
        g.add_grid_edges(nodes, weights=capy, structure=_DOWN, symmetric=False)
    # source cap = cost of ending in the sink segment (x = 1)
    g.add_grid_tedges(nodes, np.maximum(du, 0.0), np.maximum(-du, 0.0))
    g.maxflow()
    return g.get_grid_segments(nodes)


def _restricted_terms_numpy(active, du, capx, capy):
    """The numpy reference of :func:`hyperlf.regularisers._kernels.restricted_terms`.

    ``du``, ``capx``, ``capy`` are the move's terms as if every pixel were a variable (see
    :func:`graphcut`'s notes).  A fixed pixel ``p`` has ``x_p = 0``, so the pairwise term
    ``cap * (1 - x_p) * x_q`` becomes ``cap * x_q``: its capacity moves into ``q``'s unary
    term; with ``q`` fixed the term vanishes.  Returns ``(d, src, dst, caps)``: the active
    pixels' unary terms in row-major order, and the pairs between active pixels by their
    row-major ranks.
    """
    H, W = active.shape
    du = du.copy()
    idx = np.full((H, W), -1, dtype=np.int64)
    idx[active] = np.arange(int(active.sum()))
    src, dst, caps = [], [], []
    for cap, ap, aq, ip, iq, sl_q in (
            (capx[:, :-1], active[:, :-1], active[:, 1:], idx[:, :-1], idx[:, 1:],
             (slice(None), slice(1, None))),
            (capy[:-1, :], active[:-1, :], active[1:, :], idx[:-1, :], idx[1:, :],
             (slice(1, None), slice(None)))):
        du[sl_q] += np.where(~ap & aq, cap, 0.0)
        both = ap & aq
        src.append(ip[both])
        dst.append(iq[both])
        caps.append(cap[both])
    return du[active], np.concatenate(src), np.concatenate(dst), np.concatenate(caps)


def _restricted_move(g, active, du, capx, capy) -> np.ndarray:
    """Solve one expansion move whose variables are only the ``active`` pixels (terms:
    :func:`_restricted_terms_numpy`, computed by its numba kernel); returns the boolean
    switch map ``(H, W)``."""
    from . import _kernels

    d, src, dst, caps = _kernels.restricted_terms(active, du, capx, capy)
    nodes = g.add_nodes(d.size)
    if src.size:
        g.add_edges(nodes[src], nodes[dst], caps, np.zeros_like(caps))
    g.add_grid_tedges(nodes, np.maximum(d, 0.0), np.maximum(-d, 0.0))
    g.maxflow()
    switch = np.zeros(active.shape, dtype=bool)
    switch[active] = g.get_grid_segments(nodes)
    return switch


def _move_delta_numpy(switch, c_alpha, alpha, f, unary_f, Vm, wx, wy) -> float:
    """The numpy reference of :func:`hyperlf.regularisers._kernels.move_delta`: the energy of
    ``f`` with the ``switch`` pixels at ``alpha``, less the energy of ``f``, summed over the
    terms that change (the switched pixels' unary terms and the pairs that hold one)."""
    f_new = np.where(switch, alpha, f)
    delta = float((c_alpha[switch].astype(np.float64) - unary_f[switch]).sum())
    for w, p, q in ((wx, np.s_[:, :-1], np.s_[:, 1:]), (wy, np.s_[:-1, :], np.s_[1:, :])):
        touched = switch[p] | switch[q]
        new = Vm[f_new[p][touched], f_new[q][touched]]
        old = Vm[f[p][touched], f[q][touched]]
        delta += float((w[touched] * (new - old)).sum())
    return delta


class _Expansion:
    """State of one alpha-expansion run: the labelling, its unary terms and its energy.

    An accepted move updates ``f`` and ``unary_f`` in place and the energy by the move's change
    (:func:`hyperlf.regularisers._kernels.move_delta`), which reads only the switched pixels;
    :meth:`exact_energy` recomputes it over the whole image, as each cycle ends.
    """

    def __init__(self, c, f, Vm, wx, wy, candidates):
        import maxflow

        H, W = f.shape
        self.c, self.Vm, self.wx, self.wy, self.candidates = c, Vm, wx, wy, candidates
        self.f = f
        self.unary_f = gather(c, f)
        self.energy = _energy(f, self.unary_f, Vm, wx, wy)
        self.capx = np.zeros((H, W), dtype=np.float64)
        self.capy = np.zeros((H, W), dtype=np.float64)
        self.graph = maxflow.Graph[float](H * W, 2 * H * W)

    def move(self, alpha: int) -> bool:
        """Try the expansion move for ``alpha``; True when it lowered the energy."""
        from . import _kernels

        f = self.f
        du = _move_terms(self.c, alpha, f, self.unary_f, self.Vm, self.wx, self.wy,
                         self.capx, self.capy)
        self.graph.reset()                       # reuse the allocation
        if self.candidates is None:
            switch = _full_move(self.graph, du, self.capx, self.capy) & (f != alpha)
        else:
            active = self.candidates[alpha] & (f != alpha)
            if not active.any():
                return False
            switch = _restricted_move(self.graph, active, du, self.capx, self.capy)
        if not switch.any():
            return False
        c_alpha = self.c[alpha]
        delta = _kernels.move_delta(switch, c_alpha, alpha, f, self.unary_f, self.Vm, self.wx,
                                    self.wy)
        if delta < -1e-12 * max(1.0, abs(self.energy)):
            f[switch] = alpha
            self.unary_f[switch] = c_alpha[switch]
            self.energy += delta
            return True
        return False

    def exact_energy(self) -> float:
        """Recompute the energy over the whole image (removes the updates' rounding)."""
        self.energy = _energy(self.f, self.unary_f, self.Vm, self.wx, self.wy)
        return self.energy


def _progress_hooks(progress, n_moves: int):
    """(tqdm bar or None, callback or None) for graphcut's ``progress`` argument."""
    if progress is True:
        from tqdm.auto import tqdm
        return tqdm(total=n_moves, desc="alpha-expansion", unit="move"), None
    if callable(progress):
        return None, progress
    return None, None


def _check_graphcut_options(c, order, candidates):
    choice(order, "order", ("sequential", "random"))
    if candidates is not None:
        candidates = np.asarray(candidates)
        if candidates.dtype != bool or candidates.shape != c.shape:
            raise InvalidInputError(
                f"candidates must be a boolean mask of the cost's shape {c.shape}, "
                f"got {candidates.dtype} {candidates.shape}")
    return candidates


def _run_cycles(state: _Expansion, L, max_cycles, order, seed, bar, callback):
    """Cycles over all labels until one brings no improvement or ``max_cycles`` ran."""
    rng = np.random.default_rng(seed)
    for cycle in range(1, max_cycles + 1):
        improved = False
        seq = rng.permutation(L) if order == "random" else range(L)
        for alpha in seq:
            improved |= state.move(int(alpha))
            if bar is not None:
                bar.update(1)
        state.exact_energy()
        if callback is not None:
            callback(cycle, max_cycles, state.energy)
        if not improved:
            break


def graphcut(cost, smoothness: str = "truncated_linear", weight: float = 1.0,
             truncation: float | None = None, guide=None, edge_sigma: float | None = None,
             init=None, max_cycles: int = 5, labels=None, *, edge_weights=None,
             order: str = "sequential", seed: int = 0, candidates=None,
             progress: bool | Callable | None = None, return_energy: bool = False):
    """Alpha-expansion on the 4-connected grid, with PyMaxflow.

    Minimises ``E(f) = sum_p cost[f_p, p] + sum_pq w_pq V(f_p, f_q)`` (module docstring).

    Parameters
    ----------
    cost : array_like, shape (L, H, W)
        Finite cost volume (typically :func:`data_term` of a matching cost).
    smoothness : {"truncated_linear", "potts"}
        ``V = min(|labels[a] - labels[b]|, truncation)`` in disparity units (no truncation
        when ``truncation`` is None), or ``V = [a != b]``.  Both are metrics, so every
        expansion move is a submodular binary problem solved exactly by one max-flow.
    weight : float
        lambda, multiplies every pairwise term.
    truncation : float, optional
        ``T`` of the truncated-linear term.
    guide : array_like, shape (H, W) or (H, W, K), optional
        Image for contrast-sensitive weights ``exp(-||I_p - I_q||^2 / (2 edge_sigma^2))``
        (:func:`edge_weights_from_guide`).
    edge_sigma : float, optional
        Default: the guide's RMS neighbour difference.
    init : array_like of int, shape (H, W), optional
        Initial label map (default: WTA of ``cost``).
    max_cycles : int
        Maximum number of cycles over all labels; stops earlier when a whole cycle brings no
        improvement.
    labels : array_like, shape (L,), optional
        Disparity of each label (default ``0..L-1``).
    edge_weights : (wx (H, W-1), wy (H-1, W)), optional
        Explicit factors (e.g. lowered across occlusion boundaries); they multiply ``weight``
        and the guide factors, if any.
    order : {"sequential", "random"}
        Labels 0..L-1 each cycle, or a fresh permutation each cycle from ``seed``.
    seed : int
        Seed of the random order.
    candidates : array_like of bool, shape (L, H, W), optional
        The labels each pixel may *move to* (e.g. :func:`candidate_labels` of an aggregated
        volume).  The move for ``alpha`` then only has variables at pixels whose mask allows
        ``alpha``; every other pixel keeps its label and its pairwise terms with the move's
        variables are folded into their unary terms, so each move is still solved exactly over
        the pixels it may change and the energy never rises.  A move's graph only holds those
        pixels, which is where the speed comes from; the price is that a pixel can never reach
        a label outside its mask.  None (default): every label everywhere, i.e. plain
        alpha-expansion; an all-True mask gives exactly the plain moves.
    progress : bool or callable, optional
        None/False (silent), True (a tqdm bar over expansion moves) or a callable
        ``progress(cycle, n_cycles, energy)`` called after every cycle (cycle 0 = initial).
    return_energy : bool
        Also return the final energy.

    Returns
    -------
    ndarray, int32, shape (H, W)
        The label map (and the energy, a float, when ``return_energy``).

    Notes
    -----
    Each move: binary variable ``x_p = 1`` means "switch to alpha". For a neighbour pair the
    move energy ``E(x_p, x_q)`` has ``E00 = V(f_p, f_q)``, ``E01 = V(f_p, α)``,
    ``E10 = V(α, f_q)``, ``E11 = 0`` (times ``w_pq``) and is written as
    ``E00 + (E10 - E00) x_p + (E11 - E10) x_q + (E01 + E10 - E00 - E11) (1 - x_p) x_q``; the
    last coefficient is >= 0 by the triangle inequality (clipped at 0 against round-off) [2]_.
    The terms are assembled by numba kernels (their numpy references are in this module); the
    graph uses ``add_grid_edges`` (one directed edge per pair) and ``add_grid_tedges``.  A move
    is accepted only if the energy's change, summed over the terms it changes, is negative, so
    the energy never rises; the energy is recomputed over the whole image as each cycle ends.

    References
    ----------
    .. [1] Y. Boykov, O. Veksler, R. Zabih, "Fast approximate energy minimization via graph
       cuts", IEEE Trans. Pattern Anal. Mach. Intell. 23(11), 1222-1239, 2001.
       https://doi.org/10.1109/34.969114
    .. [2] V. Kolmogorov, R. Zabih, "What energy functions can be minimized via graph cuts?",
       IEEE Trans. Pattern Anal. Mach. Intell. 26(2), 147-159, 2004.
       https://doi.org/10.1109/TPAMI.2004.1262177

    Examples
    --------
    One pixel of a row prefers label 1 by 0.6; keeping it at label 0 saves two pairwise terms
    of 0.5 each, so the cut overrules it where winner-takes-all does not:

    >>> import numpy as np
    >>> from hyperlf.regularisers import wta
    >>> c = np.ones((2, 1, 5), np.float32); c[0] = 0.0
    >>> c[:, 0, 2] = [0.6, 0.0]
    >>> wta(c).tolist(), graphcut(c, weight=0.5).tolist()
    ([[0, 0, 1, 0, 0]], [[0, 0, 0, 0, 0]])
    """
    c = check_cost(cost)
    L, H, W = c.shape
    Vm = _smoothness_matrix(smoothness, L, labels, truncation)
    wx, wy = _pair_weights(H, W, weight, guide, edge_sigma, edge_weights)
    max_cycles = integer(max_cycles, "max_cycles")
    candidates = _check_graphcut_options(c, order, candidates)
    seed, return_energy = integer(seed, "seed"), flag(return_energy, "return_energy")
    f = np.argmin(c, axis=0).astype(np.intp) if init is None else \
        check_label_map(init, L, H, W, "init").copy()
    state = _Expansion(c, f, Vm, wx, wy, candidates)
    bar, callback = _progress_hooks(progress, max_cycles * L)
    if callback is not None:
        callback(0, max_cycles, state.energy)
    try:
        _run_cycles(state, L, max_cycles, order, seed, bar, callback)
    finally:
        if bar is not None:
            bar.close()
    out = state.f.astype(np.int32)
    return (out, state.energy) if return_energy else out



# ----------------------------------------------------------------------------------------------
# coarse to fine
# ----------------------------------------------------------------------------------------------

def _coarse_problem(c, g):
    """Half-resolution data term (label ``j`` = min of fine ``2j``, ``2j+1``) and guide."""
    L = c.shape[0]
    cp = np.concatenate([c, c[-1:]], axis=0) if L % 2 else c
    coarse = block_reduce(np.minimum(cp[0::2], cp[1::2])).astype(np.float32)
    g_c = None if g is None else block_reduce(np.moveaxis(g, -1, 0))
    g_c = None if g_c is None else np.moveaxis(g_c, 0, -1)
    return coarse, g_c


def _fine_start(c, fc, band, radius):
    """Initial fine labels and the candidate mask around the upsampled coarse answer."""
    from scipy import ndimage as ndi

    L, H, W = c.shape
    up = np.repeat(np.repeat(fc, 2, axis=0), 2, axis=1)[:H, :W].astype(np.intp)
    size = 2 * int(radius) + 1
    lo = 2 * ndi.minimum_filter(up, size=size) - int(band)
    hi = 2 * ndi.maximum_filter(up, size=size) + 1 + int(band)
    lab = np.arange(L)[:, None, None]
    cand = (lab >= lo[None]) & (lab <= hi[None])
    f0 = np.minimum(2 * up, L - 1)
    f1 = np.minimum(2 * up + 1, L - 1)
    init = np.where(gather(c, f1) < gather(c, f0), f1, f0)
    return init, cand


def graphcut_multiscale(cost, smoothness: str = "truncated_linear", weight: float = 1.0,
                        truncation: float | None = None, guide=None,
                        edge_sigma: float | None = None, max_cycles: int = 2,
                        labels=None, *, levels: int = 1, band: int = 2, radius: int = 2,
                        min_size: int = 16, progress: bool | None = None,
                        return_energy: bool = False):
    """Coarse-to-fine alpha-expansion: :func:`graphcut` on a half-resolution problem, then at
    full resolution with each pixel's moves restricted to labels near the coarse answer.

    The coarse problem halves the image (2x2 mean of the data term and of the guide; odd sizes
    edge-replicated) and the label set (label ``j`` = fine label ``2j``, its data term the
    lower of fine labels ``2j`` and ``2j + 1``).  Label *values* stay in fine disparity units,
    and ``weight`` is halved so that data and smoothness keep their fine-level balance (a
    coarse pixel averages 4 fine data terms; a coarse edge stands for 2 fine edges).  The fine
    problem starts from the upsampled coarse labels (the better of ``2j``, ``2j + 1`` by data
    term) and may move each pixel to fine labels in ``[2 min - band, 2 max + 1 + band]``, where
    min/max run over the coarse labels within ``radius`` pixels (coarse-label neighbourhoods
    let a thin structure the coarse level blurred come back).  ``levels > 1`` recurses.
    Exactness is traded for speed: the result is not guaranteed to have an energy below the
    WTA labelling's (plain :func:`graphcut` is).

    Parameters
    ----------
    cost, smoothness, weight, truncation, guide, edge_sigma, labels
        As in :func:`graphcut` (explicit ``edge_weights`` are not supported here).
    max_cycles : int
        Expansion cycles at each level.
    levels : int
        Number of halvings (0: plain :func:`graphcut`).  Stops early when the coarse image
        would be smaller than ``min_size`` pixels or have fewer than 4 labels.
    band : int
        Extra fine labels allowed on each side of the coarse neighbourhood's range.
    radius : int
        Coarse-neighbourhood radius in fine pixels.
    min_size : int
        Smallest coarse image side.
    progress : bool, optional
        Forwarded to the fine level's :func:`graphcut`.
    return_energy : bool
        Also return the fine-level energy.

    Returns
    -------
    ndarray, int32, shape (H, W)
        The label map (and its energy when ``return_energy``).

    See Also
    --------
    graphcut : The alpha-expansion run at each level, with the papers it follows.

    Examples
    --------
    >>> import numpy as np
    >>> c = np.random.default_rng(0).random((8, 40, 40)).astype(np.float32)
    >>> graphcut_multiscale(c, weight=0.2, truncation=2.0, levels=1, min_size=8).shape
    (40, 40)
    """
    c = check_cost(cost)
    L, H, W = c.shape
    levels, band, radius, min_size = (integer(v, name) for v, name in (
        (levels, "levels"), (band, "band"), (radius, "radius"), (min_size, "min_size")))
    flag(return_energy, "return_energy")
    lv = check_labels(labels, L)
    g = None if guide is None else check_guide(guide, H, W)
    common = dict(smoothness=smoothness, truncation=truncation, edge_sigma=edge_sigma,
                  max_cycles=max_cycles)
    if levels == 0 or min(H, W) < 2 * min_size or L < 8:
        return graphcut(c, weight=weight, guide=g, labels=lv, progress=progress,
                        return_energy=return_energy, **common)
    coarse, g_c = _coarse_problem(c, g)
    fc = graphcut_multiscale(coarse, weight=0.5 * float(weight), guide=g_c, labels=lv[0::2],
                             levels=levels - 1, band=band, radius=radius, min_size=min_size,
                             **common)
    init, cand = _fine_start(c, fc, band, radius)
    return graphcut(c, weight=weight, guide=g, labels=lv, init=init, candidates=cand,
                    progress=progress, return_energy=return_energy, **common)
