"""The tabulated A-functions of one configuration and their interpolation.

:class:`ATable` holds ``ln A_1`` and ``ln A_2`` (Smalikho (2020), eqs. 15-17) on a grid
of heights, ``mu = U/V_s``, lags and, for the finite-outer-scale models, ``L_V``
(computed and cached by :mod:`cwproc.physics.atable`); ``log A`` is interpolated with
4-point Lagrange (cubic) weights along each axis (``log h``, ``mu``, ``log L_V``), the
lags are the integers ``1..n_lags``; outside the grid the tables give NaN.
:class:`CellTable` is a table fixed at cells, a function of ``L_V`` only. ``A_2`` of
inertial tables is also kept per azimuth node (:func:`azimuth_nodes`), so sectors and
gaps average it over the azimuths of the pairs present (:func:`azimuth_bin_weights`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

#: azimuth nodes of A_2 stored beside its circle average (inertial tables), equally
#: spaced on the circle of the wind's angle from the scan direction (10 deg)
N_BINS = 36


def lagrange4(nodes: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices ``(q, 4)``, weights ``(q, 4)`` of cubic Lagrange interpolation, and validity.

    Near the ends the 4-point stencil is shifted inwards; points outside ``[nodes[0],
    nodes[-1]]`` are flagged invalid.
    """
    x = np.asarray(x, dtype=float).ravel()
    n = nodes.size
    valid = (x >= nodes[0] - 1e-12 * abs(nodes[0])) & (x <= nodes[-1] + 1e-12 * abs(nodes[-1]))
    valid &= np.isfinite(x)
    xc = np.clip(np.where(np.isfinite(x), x, nodes[0]), nodes[0], nodes[-1])
    if n < 4:
        raise ValueError("an interpolation axis needs at least 4 nodes")
    i = np.clip(np.searchsorted(nodes, xc, side="right") - 2, 0, n - 4)
    idx = i[:, None] + np.arange(4)[None, :]
    xn = nodes[idx]  # (q, 4)
    w = np.ones((x.size, 4))
    for j in range(4):
        for k in range(4):
            if j != k:
                w[:, j] *= (xc - xn[:, k]) / (xn[:, j] - xn[:, k])
    return idx, w, valid


@dataclass(frozen=True)
class ATable:
    """Tabulated ``A_1 = A_perp(l dy)`` and ``A_2(l dy; mu)`` of one configuration.

    Attributes
    ----------
    heights_m : (nh,) heights (m) of the nodes.
    mu : (nm,) nodes of ``mu = U / V_s``.
    outer_scales_m : (nL,) nodes of ``L_V`` (m); ``(1,)`` NaN for the inertial model.
    log_a1 : (nL, nh, n_lags) ``ln A_1`` (A in m^(2/3)).
    log_a2 : (nL, nh, n_lags, nm) ``ln A_2``, the average over the full circle.
    params : the parameters the table was built for (also its cache key).
    bins_a2 : (1, nh, n_lags, nm, N_BINS) inertial tables: eq. 15's integrand at the
        azimuth nodes (:func:`azimuth_nodes`) divided by the circle average;
        ``None`` for finite-outer-scale tables (the estimator applies the inertial
        table's sector ratio to them, times :meth:`scale_ratio`).
    scale_bins : (nL, n_lags, nm, N_BINS) finite-outer-scale tables of pulsed probes:
        their per-node ratio (as ``bins_a2``) over that of the inertial model at the
        height :attr:`scale_height_m`; ``None`` otherwise.
    """

    heights_m: np.ndarray
    mu: np.ndarray
    outer_scales_m: np.ndarray
    log_a1: np.ndarray
    log_a2: np.ndarray
    params: dict = field(default_factory=dict)
    bins_a2: np.ndarray | None = None
    scale_bins: np.ndarray | None = None

    @property
    def scale_height_m(self) -> float:
        """The height (m) of ``scale_bins``: the middle height node."""
        return float(self.heights_m[self.heights_m.size // 2])

    def scale_ratio(
        self, lags: ArrayLike, height_m: ArrayLike, mu: ArrayLike, outer_scale_m: ArrayLike
    ) -> np.ndarray:
        """``(..., N_BINS)``: the per-node A_2 ratio of the outer scale over the inertial one.

        The finite-outer-scale A_2 at azimuth node ``n`` over its circle mean is the
        inertial table's (``bins_a2``) times this factor. The outer scale acts through
        the separations over ``L_V``, and the separations scale with the height (``dy =
        dtheta h / tan(phi)``), so ``scale_bins`` at :attr:`scale_height_m` is read at
        ``L_V h_ref / h`` (linear in ``log L_V``, clamped to the nodes; cubic in ``mu``).
        1 for tables without ``scale_bins``.
        """
        lags_b, h_b, mu_b, l_b = np.broadcast_arrays(
            np.asarray(lags, float),
            np.asarray(height_m, float),
            np.asarray(mu, float),
            np.asarray(outer_scale_m, float),
        )
        shape = lags_b.shape
        if self.scale_bins is None:
            return np.ones((*shape, N_BINS))
        s_mu = self._scale_mu(lags_b.ravel(), mu_b.ravel())
        out = self._interp_scale(s_mu, h_b.ravel(), l_b.reshape(-1, 1))
        return out[:, 0].reshape(*shape, N_BINS)

    def scale_ratio_sums(
        self,
        lags: ArrayLike,
        height_m: ArrayLike,
        mu: ArrayLike,
        outer_scales_m: ArrayLike,
        vectors: np.ndarray,
    ) -> np.ndarray:
        """``(q, nS, m)``: ``sum_n scale_ratio[q, s, n] vectors[q, j, n]`` at ``nS`` outer scales.

        The contractions of :meth:`scale_ratio` of ``q`` points (``lags``, ``height_m``,
        ``mu`` broadcast to ``(q,)``) with ``m`` node vectors each (``vectors``, ``(q, m,
        N_BINS)``), at every outer scale, without forming the ``(q, nS, N_BINS)`` ratios:
        the contraction is done at the table's nodes of ``L_V`` and then interpolated
        (both are linear).
        """
        lags_b, h_b, mu_b = (
            a.ravel()
            for a in np.broadcast_arrays(
                np.asarray(lags, float), np.asarray(height_m, float), np.asarray(mu, float)
            )
        )
        vectors = np.asarray(vectors, float)
        scales = np.asarray(outer_scales_m, float).ravel()
        if self.scale_bins is None:
            total = vectors.sum(axis=-1)
            return np.broadcast_to(total[:, None, :], (lags_b.size, scales.size, total.shape[-1]))
        li = np.clip(np.nan_to_num(lags_b, nan=1.0), 1, self.n_lags).astype(int) - 1
        im, wm, _ = lagrange4(self.mu, np.clip(np.nan_to_num(mu_b), 0.0, self.mu[-1]))
        # points sharing a lag and a mu stencil (a few hundred groups for any number of
        # points) contract one (nK * 4, N) block of the table as a matrix product
        key = li * self.mu.size + im[:, 0]
        order = np.argsort(key, kind="stable")
        bounds = np.flatnonzero(np.diff(key[order])) + 1
        n_k, n_v = self.outer_scales_m.size, vectors.shape[1]
        at_nodes = np.empty((n_k, lags_b.size, n_v))
        for group in np.split(order, bounds):
            block = self.scale_bins[:, li[group[0]], im[group[0]]].reshape(-1, N_BINS)
            prod = vectors[group].reshape(-1, N_BINS) @ block.T  # (g * m, nK * 4)
            prod = prod.reshape(group.size, n_v, n_k, 4)
            at_nodes[:, group] = np.einsum("gjkc,gc->kgj", prod, wm[group])
        big_l = np.broadcast_to(scales[None, :], (lags_b.size, scales.size))
        return self._interp_scale(at_nodes, h_b, big_l)

    def _scale_mu(self, lags: np.ndarray, mu: np.ndarray) -> np.ndarray:
        """``(nK, q, N)``: ``scale_bins`` at the points' lags and ``mu`` (cubic), every node."""
        li = np.clip(np.nan_to_num(lags, nan=1.0), 1, self.n_lags).astype(int) - 1
        im, wm, _ = lagrange4(self.mu, np.clip(np.nan_to_num(mu), 0.0, self.mu[-1]))
        return np.einsum("kqcn,qc->kqn", self.scale_bins[:, li[:, None], im], wm)

    def _interp_scale(
        self, at_nodes: np.ndarray, height_m: np.ndarray, outer_scale_m: np.ndarray
    ) -> np.ndarray:
        """``(q, nS, ...)``: ``at_nodes`` ``(nK, q, ...)`` read at ``L_V h_ref / h`` (linear in
        ``log L_V``, clamped to the nodes) for the ``(q, nS)`` outer scales."""
        nodes = np.log(self.outer_scales_m)
        with np.errstate(invalid="ignore", divide="ignore"):
            x = np.log(outer_scale_m * self.scale_height_m / height_m[:, None])
        x = np.clip(np.nan_to_num(x, nan=nodes[0]), nodes[0], nodes[-1])
        k = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2)
        frac = (x - nodes[k]) / (nodes[k + 1] - nodes[k])
        frac = frac.reshape(*frac.shape, *([1] * (at_nodes.ndim - 2)))
        rows = np.arange(at_nodes.shape[1])[:, None]
        return (1.0 - frac) * at_nodes[k, rows] + frac * at_nodes[k + 1, rows]

    @property
    def n_lags(self) -> int:
        """Number of lags ``l = 1..n_lags`` in the table."""
        return self.log_a1.shape[-1]

    @property
    def model(self) -> str:
        """Spectrum model of the table."""
        return str(self.params["model"])

    def dy(self, height_m: ArrayLike) -> np.ndarray:
        """Nominal transverse sampling ``dy = dtheta h / tan(phi)`` (m) at ``height_m`` (m).

        A cw probe with a known beam radius samples a circle of a smaller radius
        (:meth:`cwproc.physics.transfer.CWProbe.centre_range`); the table's lags use it.
        """
        phi = math.radians(self.params["phi_deg"])
        return math.radians(self.params["delta_theta_deg"]) * np.asarray(height_m) / math.tan(phi)

    def evaluate(
        self,
        lags: ArrayLike,
        height_m: ArrayLike,
        mu: ArrayLike,
        outer_scale_m: ArrayLike | None = None,
        weights: ArrayLike | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(A_1, A_2)`` (m^(2/3)) at lag numbers, heights, ``mu`` and outer scales.

        Parameters
        ----------
        lags : array_like of int
            Lag numbers ``l`` in ``1..n_lags``.
        height_m : array_like
            Heights (m) above the lidar.
        mu : array_like
            ``U / V_s`` (1).
        outer_scale_m : array_like, optional
            ``L_V`` (m); required for finite-outer-scale tables, ignored otherwise.
        weights : array_like, optional
            ``(..., N_BINS)``: the share of the pairs present in each azimuth bin
            (:func:`azimuth_bin_weights`); ``None`` gives the full-circle average of
            Smalikho (2020), eq. 15 (tables without bins ignore it).

        All inputs broadcast. Points outside the tabulated ranges give NaN.
        """
        finite_l = self.model != "inertial"
        if finite_l and outer_scale_m is None:
            raise ValueError(f"a {self.model!r} table needs outer_scale_m")
        lval = outer_scale_m if finite_l else np.nan
        lags_b, h_b, mu_b, l_b = np.broadcast_arrays(
            np.asarray(lags), np.asarray(height_m, float), np.asarray(mu, float), np.asarray(lval)
        )
        shape = lags_b.shape
        lag = np.asarray(lags_b, dtype=float).ravel()
        lag_ok = (lag >= 1) & (lag <= self.n_lags) & (lag == np.round(lag))
        li = np.clip(np.where(np.isfinite(lag), lag, 1), 1, self.n_lags).astype(int) - 1
        with np.errstate(divide="ignore", invalid="ignore"):
            im, wm, vm = lagrange4(self.mu, mu_b.ravel())
            if finite_l:
                il, wl, vl = lagrange4(
                    np.log(self.outer_scales_m), np.log(l_b.astype(float).ravel())
                )
            else:
                il = np.zeros((lag.size, 1), int)
                wl = np.ones((lag.size, 1))
                vl = np.ones(lag.size, bool)
        # Interpolate in height first, once per distinct height (a day of blocks shares a
        # few hundred heights), then gather only the 4 x 4 (L_V, mu) neighbours per point.
        h_flat = h_b.ravel()
        h_unique, h_inverse = np.unique(h_flat, return_inverse=True)
        h_inverse = h_inverse.ravel()
        with np.errstate(divide="ignore", invalid="ignore"):
            ihu, whu, vhu = lagrange4(np.log(self.heights_m), np.log(h_unique))
        vh = vhu[h_inverse]
        # (nL, n_unique, n_lag) and (nL, n_unique, n_lag, nm)
        a1_h = np.einsum("lukj,uk->luj", self.log_a1[:, ihu, :], whu)
        a2_h = np.einsum("lukjm,uk->lujm", self.log_a2[:, ihu, :, :], whu)
        n_u, n_lag, n_m = h_unique.size, self.n_lags, self.mu.size
        base = (il * n_u + h_inverse[:, None]) * n_lag + li[:, None]  # (q, a)
        log1 = np.einsum("qa,qa->q", wl, a1_h.ravel().take(base))
        vals2 = a2_h.ravel().take(base[:, :, None] * n_m + im[:, None, :])  # (q, a, 4)
        log2 = np.einsum("qa,qac,qc->q", wl, vals2, wm, optimize=True)
        if weights is not None and self.bins_a2 is not None:
            wb = np.broadcast_to(np.asarray(weights, float), (*shape, N_BINS))
            wb = wb.reshape(-1, N_BINS)
            ratio = self._node_ratio((ihu, whu), base, (im, wm), wl)
            log2 = log2 + np.log(np.maximum(np.sum(ratio * wb, axis=-1), 1e-12))
        ok1 = lag_ok & vh & vl
        ok2 = ok1 & vm
        out1 = np.where(ok1, np.exp(log1), np.nan).reshape(shape)
        out2 = np.where(ok2, np.exp(log2), np.nan).reshape(shape)
        return out1, out2

    def _node_ratio(self, height: tuple, base: np.ndarray, mu: tuple, wl: np.ndarray) -> np.ndarray:
        """``(q, N_BINS)`` ``bins_a2`` interpolated: height stencil ``(ihu, whu)`` of the
        distinct heights, ``base`` ``(q, a)`` flat (outer scale, height, lag) rows, ``mu``
        stencil ``(im, wm)`` and outer-scale weights ``wl`` (as :meth:`evaluate`)."""
        ihu, whu = height
        im, wm = mu
        r_h = np.einsum("lukjmc,uk->lujmc", self.bins_a2[:, ihu], whu)
        flat = r_h.reshape(-1, N_BINS)
        idx = base[:, :, None] * self.mu.size + im[:, None, :]  # (q, a, 4)
        vals = flat[idx.ravel()].reshape(*idx.shape, N_BINS)  # (q, a, 4, bins)
        return np.einsum("qa,qacn,qc->qn", wl, vals, wm, optimize=True)

    def node_ratio(self, lags: ArrayLike, height_m: ArrayLike, mu: ArrayLike) -> np.ndarray:
        """``(..., N_BINS)``: ``A_2`` at each azimuth node over its circle mean (inertial).

        The factor :meth:`evaluate` applies for ``weights`` (``A_2(weights) = A_2 *
        sum(node_ratio * weights)``), for callers that weight the same cells many times.
        Inputs broadcast; 1 for tables without bins.
        """
        lags_b, h_b, mu_b = np.broadcast_arrays(
            np.asarray(lags, float), np.asarray(height_m, float), np.asarray(mu, float)
        )
        shape = lags_b.shape
        if self.bins_a2 is None:
            return np.ones((*shape, N_BINS))
        lag = lags_b.ravel()
        li = np.clip(np.nan_to_num(lag, nan=1.0), 1, self.n_lags).astype(int) - 1
        h_unique, h_inverse = np.unique(h_b.ravel(), return_inverse=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            ihu, whu, _ = lagrange4(np.log(self.heights_m), np.log(h_unique))
            im, wm, _ = lagrange4(self.mu, mu_b.ravel())
        base = (h_inverse.ravel() * self.n_lags + li)[:, None]  # one (nan) outer-scale node
        ratio = self._node_ratio((ihu, whu), base, (im, wm), np.ones((lag.size, 1)))
        return ratio.reshape(*shape, N_BINS)

    def at_cells(self, lags: ArrayLike, height_m: ArrayLike, mu: ArrayLike) -> CellTable:
        """This table interpolated in height and ``mu`` to fixed cells, kept over ``L_V``.

        For root searches in ``L_V`` (:mod:`cwproc.stages.epsilon`): the height and
        ``mu`` weights of :meth:`evaluate` are applied once, so each later evaluation
        at new outer scales only interpolates in ``log L_V`` (the same 4-point Lagrange
        weights: equal to :meth:`evaluate` up to rounding).

        Parameters
        ----------
        lags : array_like of int
            ``(n_lag,)`` lag numbers in ``1..n_lags``.
        height_m, mu : array_like
            ``(cells,)`` heights (m) and ``mu = U / V_s``.
        """
        lag = np.asarray(lags, dtype=float).ravel()
        h = np.asarray(height_m, dtype=float).ravel()
        li = np.clip(np.where(np.isfinite(lag), lag, 1), 1, self.n_lags).astype(int) - 1
        lag_ok = (lag >= 1) & (lag <= self.n_lags) & (lag == np.round(lag))
        h_unique, h_inverse = np.unique(h, return_inverse=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            ihu, whu, vhu = lagrange4(np.log(self.heights_m), np.log(h_unique))
            im, wm, vm = lagrange4(self.mu, np.asarray(mu, dtype=float).ravel())
        h_inverse = h_inverse.ravel()
        a1_h = np.einsum("lukj,uk->luj", self.log_a1[:, ihu, :], whu)[:, h_inverse][..., li]
        a2_h = np.einsum("lukjm,uk->lujm", self.log_a2[:, ihu, :, :], whu)[..., li, :]
        # per outer-scale node: gather the (cells, n_lag, 4) mu neighbours, then weight
        rows, cols = h_inverse[:, None, None], np.arange(li.size)[None, :, None]
        log_a2 = np.stack(
            [np.einsum("qjc,qc->qj", node[rows, cols, im[:, None, :]], wm) for node in a2_h],
            axis=1,
        )
        valid = lag_ok[None, :] & vhu[h_inverse][:, None]
        return CellTable(
            np.log(self.outer_scales_m), np.moveaxis(a1_h, 0, 1), log_a2, valid, valid & vm[:, None]
        )


@dataclass(frozen=True)
class CellTable:
    """An :class:`ATable` at fixed cells and lags, a function of ``L_V`` (:meth:`ATable.at_cells`).

    Attributes
    ----------
    log_scales : (nL,) ``ln L_V`` of the nodes (L_V in m).
    log_a1, log_a2 : (cells, nL, n_lag) ``ln A_1``, ``ln A_2`` at the nodes.
    valid1, valid2 : (cells, n_lag) height, lag (and for A_2, ``mu``) in range.
    """

    log_scales: np.ndarray
    log_a1: np.ndarray
    log_a2: np.ndarray
    valid1: np.ndarray
    valid2: np.ndarray

    def evaluate(
        self, outer_scale_m: ArrayLike, cells: ArrayLike | None = None, a1: bool = True
    ) -> tuple[np.ndarray | None, np.ndarray]:
        """``(A_1, A_2)`` (m^(2/3)), ``(n, k, n_lag)``, at outer scales ``(n, k)`` (m).

        ``cells`` (``(n,)`` indices, default all) selects the rows; NaN outside the
        tabulated ranges, as :meth:`ATable.evaluate`. ``a1=False`` skips ``A_1`` (None).
        """
        n_cells, n_nodes, n_lag = self.log_a2.shape
        rows = np.arange(n_cells) if cells is None else np.asarray(cells)
        big_l = np.asarray(outer_scale_m, dtype=float)
        n, k = big_l.shape
        with np.errstate(divide="ignore", invalid="ignore"):
            il, wl, vl = lagrange4(self.log_scales, np.log(big_l).ravel())
        r = np.repeat(rows, k)
        flat = r[:, None] * n_nodes + il  # (q, 4) rows of the (cells * nL, n_lag) tables
        out = []
        for table, valid in ((self.log_a1, self.valid1), (self.log_a2, self.valid2))[1 - a1 :]:
            log_a = np.einsum("qa,qaj->qj", wl, table.reshape(-1, n_lag).take(flat, axis=0))
            ok = valid.take(r, axis=0) & vl[:, None]
            out.append(np.where(ok, np.exp(log_a), np.nan).reshape(n, k, n_lag))
        return (out[0] if a1 else None), out[-1]


def azimuth_nodes() -> np.ndarray:
    """The ``N_BINS`` node azimuths (rad) of ``bins_a2``, equally spaced on the circle."""
    return 2.0 * np.pi * np.arange(N_BINS) / N_BINS


def _node_interpolation(theta: np.ndarray) -> np.ndarray:
    """Periodic linear-interpolation weights ``(..., N_BINS)`` of azimuths on the nodes."""
    step = 2.0 * np.pi / N_BINS
    pos = np.mod(np.asarray(theta, dtype=float), 2.0 * np.pi) / step
    i0 = np.floor(pos).astype(int) % N_BINS
    frac = pos - np.floor(pos)
    out = np.zeros((*pos.shape, N_BINS))
    np.put_along_axis(out, i0[..., None], (1.0 - frac)[..., None], axis=-1)
    np.put_along_axis(out, ((i0 + 1) % N_BINS)[..., None], frac[..., None], axis=-1)
    return out


def azimuth_bin_weights(
    theta: ArrayLike, axis: int = -1, counts: ArrayLike | None = None
) -> np.ndarray:
    """Weights ``(..., N_BINS)`` of the azimuth nodes for the pairs at ``theta`` (rad).

    ``theta`` (along ``axis``) is the angle of the mean wind from the scan's direction of
    motion at each pair present (Smalikho (2020), eq. 15: the wind's component along the
    scan is ``U sin th``, along the horizontal beam ``U cos th``); each pair is shared
    linearly between the two neighbouring nodes (:func:`azimuth_nodes`). ``counts``
    (shape of ``theta``): the number of pairs at each azimuth (default 1). NaN azimuths
    are left out; no pair at all gives NaN weights.
    """
    th = np.moveaxis(np.asarray(theta, dtype=float), axis, -1)
    n = np.ones_like(th) if counts is None else np.moveaxis(np.asarray(counts, float), axis, -1)
    n = np.where(np.isfinite(th), n, 0.0)
    w = _node_interpolation(np.where(n > 0, th, 0.0)) * n[..., None]
    total = n.sum(axis=-1)[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return w.sum(axis=-2) / total
