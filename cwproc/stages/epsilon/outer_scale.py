"""Finite outer scale: eps and L_V fitted together (Banakh et al. (1999), eqs. 17, 19).

For a finite-outer-scale model the least squares of Smalikho (2020), eq. 4 with the
model's A-functions gives ``eps(L_V)``; the root in ``L_V`` of the variance condition
(the variance of ``V'_L`` the model predicts equals the measured one) fixes both
(:func:`outer_scale_root`). :func:`fit_cells` is the whole fit of a cell from its
statistics, methods 1 and 2 included, a pure function of ``(D, variance)`` that the
delta method differentiates (:mod:`cwproc.stages.epsilon.errors`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cwproc.physics import spectra
from cwproc.physics.exact_lag import is_cw_probe
from cwproc.physics.probe_variance import averaging_loss, passed_variance, segment_loss
from cwproc.physics.removed_share import (
    MAX_SECTOR_RAYS,
    circle_removed_d,
    interp_log_scale,
    sector_removed_d,
    sector_removed_share,
)
from cwproc.physics.root_search import Residual, bracket_root, replayed_root
from cwproc.physics.scan_transport import transport_mu, transport_weight
from cwproc.physics.structure_fit import NOISE_PRIOR_REL_SE, fit_structure_function
from cwproc.stages.epsilon.atable_fit import (
    EVALUATION_CELLS,
    TableOptions,
    outer_scale_sector_factor,
)
from cwproc.stages.epsilon.cells import Cells
from cwproc.stages.epsilon.circle_share import correlated_circle_share
from cwproc.stages.epsilon.few_ray import (
    carried_scale_factor,
    few_ray_circles,
    few_ray_factor,
    few_ray_inertial_a2,
)
from cwproc.stages.epsilon.records import (
    CellEstimates,
    CellTables,
    FiniteScaleInputs,
    FitMemo,
    FitSetup,
    NoisePrior,
)
from cwproc.tables.removed_share import mean_removed_share, stored_dense_grid

#: lengths below this fraction of L_V keep the inertial A-functions (see module doc)
INERTIAL_FRACTION = 0.02
#: bisection steps of the outer-scale root (bracket ratio (3000/10)^(1/6) -> 0.2 %)
_BISECTIONS = 9
#: cells of one root search at once (each cell's search is independent of the others;
#: 16384 rather than 2048: a day's 180-ray cells in one pass, 13 % less time for the error
#: bars' retrievals, the same retrieve-day peak (283 MiB; the stream runs 40 blocks at once))
ROOT_CELLS = 16384
#: azimuth step (deg) from which full circles (at most 72 rays) get the outer scale's own
#: node ratio over the pairs present (:func:`_sector_cell_table`). 72-ray circles (5 deg)
#: need it: with the inertial ratio alone their model D(1-3) at mu 1 (L_V 150 m, 100 m
#: height) was 0.998 / 0.999 / 1.002 of the exact expectation, a shape that moved the free
#: intercept by +7 % of 2 sigma_e^2 = 0.02 m2 s-2 (sigma_e read 1.11 with the SNR x1.5);
#: with it 0.9975 / 0.9982 / 0.9988, +2.4 % (issue 29, item 2)
COARSE_STEP_DEG = 4.9
#: bisections from a bracket of a factor NEAR_FACTOR on either side of a known root
#: (-> 1.1 %)
_BISECTIONS_NEAR = 6
#: the bracket around a known root spans this factor either side of it
NEAR_FACTOR = 2.0


def finite_scale_inputs(
    probe: Any,
    model: str,
    options: TableOptions,
    uniq: np.ndarray,
    inverse: np.ndarray,
    cells: Cells,
    n_outer_scales: int,
    memo: FitMemo | None = None,
) -> FiniteScaleInputs:
    """What the finite-outer-scale fit needs besides D and the variance (per cell).

    The probe-passed variance per eps^(2/3) of the model on a log grid of L_V (ratio
    <= 1.1), per distinct (dy, range) cell
    (:func:`cwproc.physics.probe_variance.passed_variance`), less the share the block-mean
    VAD wind removes (:func:`mean_removed_share` at the cell's ``mu``, divided by the scans
    of the block; sectors and gaps (:attr:`Cells.partial`: the ``weights`` and ``dtheta``
    of the ``cells``): :func:`sector_removed_share` with the scans' ``interval`` over
    T_scan); the full variance per eps^(2/3) on that grid; the coarse L_V nodes; the
    longest length of each cell (its largest lag's separation or its probe length).
    ``memo``: see :func:`fit_setup`.
    """
    n_t, n_h = cells.range_m.shape
    scans, radius, mu_eval, weights = cells.scans, cells.radius, cells.mu_eval, cells.weights
    lo, hi = options.outer_scale_range_m
    scale_grid = np.geomspace(lo, hi, int(np.ceil(np.log(hi / lo) / np.log(1.1))) + 1)

    def passed_per_pair() -> np.ndarray:
        cells_u = np.nonzero(uniq[:, 0] >= 0)[0]
        passed_u = np.full((uniq.shape[0], scale_grid.size), np.nan)
        for start in range(0, cells_u.size, EVALUATION_CELLS):  # bounded working memory
            part = cells_u[start : start + EVALUATION_CELLS]
            passed_u[part] = passed_variance(
                probe, np.abs(uniq[part, 0]), np.abs(uniq[part, 1]), model, scale_grid
            )
        return passed_u

    passed_u = _remembered(memo, ("passed", model, scale_grid.tobytes(), uniq), passed_per_pair)
    passed_cell = passed_u[inverse.ravel()].reshape(n_t, n_h, scale_grid.size)
    full_var = np.array([spectra.variance_per_eps23(model, x) for x in scale_grid])
    n_eff = np.where(np.isfinite(scans) & (scans >= 1), scans, 1.0)
    phi_med = float(np.nanmedian(cells.phi))
    share = np.empty(passed_cell.shape)
    step = max(1, EVALUATION_CELLS // max(n_h, 1))  # blocks at once: bounded memory
    for t0 in range(0, n_t, step):
        rows = slice(t0, t0 + step)
        ratio_rl = radius[rows, :, None] / scale_grid[None, None, :]
        share[rows] = mean_removed_share(
            ratio_rl, phi_med, model, mu_eval[rows, :, None], options.cache_dir
        )
    share /= n_eff[:, None, None]
    partial = cells.partial
    ct, ch = np.nonzero(~partial & (np.rint(360.0 / cells.dtheta) <= MAX_SECTOR_RAYS)[:, None])
    if ct.size:  # circles of correlated scans: the block mean takes up to N times more
        share[ct, ch] = correlated_circle_share(
            share[ct, ch], cells, ct, ch, scale_grid, n_eff[ct], phi_med, model
        )
    ti, hi_ = np.nonzero(partial)
    if ti.size:
        share[ti, hi_] = sector_removed_share(
            weights[ti, hi_],
            radius[ti, hi_, None] / scale_grid[None, :],
            mu_eval[ti, hi_],
            cells.interval[ti],
            n_eff[ti],
            phi_med,
            model,
        )
    n_l = cells.d.shape[2]
    probe_len = np.broadcast_to(np.asarray(probe.length_scale_m(cells.range_m), float), (n_t, n_h))
    return FiniteScaleInputs(
        nodes=np.geomspace(lo, hi, n_outer_scales),
        scale_grid=scale_grid,
        passed=np.subtract(passed_cell, np.multiply(share, full_var, out=share), out=share),
        full_var=full_var,
        longest=np.maximum(n_l * cells.dy * (1 + mu_eval), probe_len),
    )


def variance_residual(
    table: Any,
    table_rows: np.ndarray,
    finite: FiniteScaleInputs,
    cell_sector: np.ndarray,
    passed: np.ndarray,
    dc: np.ndarray,
    vc: np.ndarray,
    var_c: np.ndarray,
    prior: np.ndarray,
    d_cov: np.ndarray | None = None,
    prior_rel_se: float = NOISE_PRIOR_REL_SE,
    known: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> Residual:
    """The variance condition of cells ``(n,)``, a function of ``L_V`` ``(n, k)`` (m).

    The variance of V'_L the model predicts, eps^(2/3) times the probe-passed part of
    sigma_V^2 = (eps L_V / c)^(2/3) (Banakh et al. (1999), eq. 19;
    :func:`cwproc.physics.probe_variance.passed_variance`), must equal the measured one
    minus sigma_e^2; eps(L_V) and sigma_e(L_V) from the least squares of Smalikho (2020),
    eq. 4 with the model's A_2 over all valid lags. The residual is the log of their
    ratio, rising through 0 at the root. ``table`` is the model's table at fixed cells
    (:meth:`cwproc.physics.atable_interp.ATable.at_cells`), ``table_rows`` the cells'
    rows of it; ``d_cov`` the covariance of D of the cells (``(n, lag, lag)``) that
    decides whether sigma_e is fitted, ``prior_rel_se`` the relative standard error of
    the predicted ``2 sigma_e^2``; ``known``: ``(L_V, A_2, passed)`` of these cells at
    some ``(n, k)`` outer scales (:func:`scale_parts`), used where the residual is asked
    there again.
    """
    scale_grid = finite.scale_grid
    cov = None if d_cov is None else d_cov[:, None]

    def residual(big_l: np.ndarray) -> np.ndarray:
        k = big_l.shape[1]
        if known is not None and known[0].shape == big_l.shape and np.array_equal(known[0], big_l):
            f2, through = known[1], known[2]
        else:
            big_l = np.broadcast_to(big_l, (dc.shape[0], k))
            f2, through = scale_parts(table, table_rows, cell_sector, scale_grid, passed, big_l)
        eps_l, noise_l, _ = fit_structure_function(
            dc[:, None, :], f2, vc[:, None, :], prior, cov, prior_rel_se
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            model_var = np.log(eps_l ** (2 / 3) * through)
            measured = np.log(var_c[:, None] - np.nan_to_num(noise_l, nan=0.0) ** 2)
        return np.broadcast_to(model_var - measured, (dc.shape[0], k))

    return residual


def scale_parts(
    table: Any,
    table_rows: np.ndarray,
    cell_sector: np.ndarray,
    scale_grid: np.ndarray,
    passed: np.ndarray,
    big_l: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``(A_2, passed)`` of cells ``(n,)`` at outer scales ``(n, k)`` (m): what
    :func:`variance_residual` takes from ``L_V`` alone, apart from ``D`` and the variance.

    ``A_2`` (``(n, k, lag)``, m^(2/3)) of the model's table at the cells' rows
    ``table_rows`` times their sector ratio ``cell_sector`` (``(n, lag)``), and the
    probe-passed variance per eps^(2/3) (``(n, k)``) interpolated from ``passed``
    (``(n, scale)`` on ``scale_grid``).
    """
    _, f2 = table.evaluate(big_l, table_rows, a1=False)
    return f2 * cell_sector[:, None, :], interp_log_scale(scale_grid, passed, big_l)


def _cells_residual(
    index: np.ndarray,
    table: Any,
    finite: FiniteScaleInputs,
    chunk: tuple,
    rel_se: float,
    known: tuple | None = None,
) -> Residual:
    """:func:`variance_residual` of the cells ``index`` of a chunk of cells.

    ``chunk``: the chunk's ``(n, ...)`` table rows, passed variances, sector factors, D,
    valid lags, variance, noise prediction ``(n, 1)`` and covariance of D (or None) of
    :func:`fit_cells`; ``rel_se`` the prediction's relative standard error; ``known``:
    :func:`scale_parts` of the chunk at some outer scales, with them
    (``variance_residual``'s ``known``).
    """
    rows, passed, sector, d, valid, var_raw, prior, d_cov = (
        None if c is None else _take(c, index) for c in chunk
    )
    return variance_residual(
        table,
        rows,
        finite,
        sector,
        passed,
        d,
        valid,
        var_raw,
        prior,
        d_cov,
        rel_se,
        None if known is None else tuple(_take(k, index) for k in known),
    )


def _take(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``values[index]``, or ``values`` itself where ``index`` is every row in order."""
    n = values.shape[0]
    if index.size == n and (n == 0 or (index[0] == 0 and index[-1] == n - 1)):
        if np.array_equal(index, np.arange(n)):
            return values
    return values[index]


def outer_scale_root(
    residual_of: Callable[[np.ndarray], Residual],
    n: int,
    nodes: np.ndarray,
    near: np.ndarray | None = None,
    near_slope: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(root, has_root, below, slope)`` of the variance condition in L_V (m) of ``n`` cells.

    ``residual_of(index)`` is :func:`variance_residual` of the cells ``index``. Coarse
    scan of ``nodes`` (``(k,)``, m), then :data:`_BISECTIONS` bisections of the largest
    sign change in log L_V (:func:`cwproc.physics.root_search.bracket_root`);
    ``below``: even the smallest node gives too much variance (lags not inertial);
    ``slope``: the residual's slope by log L_V at the root. With ``near`` (a root per
    cell, for the small changes of :func:`cwproc.stages.epsilon.errors.covariance_errors`)
    the scan covers ``near / 2 .. 2 near`` and :data:`_BISECTIONS_NEAR` bisections reach
    the same bracket, replayed from a secant step where ``near_slope`` (the slope at
    ``near``) is given (:func:`cwproc.physics.root_search.replayed_root`, the same
    roots from three evaluations for seven); ``slope`` is then NaN.
    """
    if near is None:
        residual = residual_of(np.arange(n))
        return bracket_root(residual, np.broadcast_to(nodes, (n, nodes.size)), _BISECTIONS)
    if near_slope is None:
        root, has_root, below, _ = bracket_root(
            residual_of(np.arange(n)), near_nodes(near), _BISECTIONS_NEAR
        )
    else:
        root, has_root, below = replayed_root(
            residual_of, near, near_slope, NEAR_FACTOR, _BISECTIONS_NEAR
        )
    return root, has_root, below, np.full(n, np.nan)


def near_nodes(near: np.ndarray) -> np.ndarray:
    """``(n, 3)``: the outer scales (m) a root search near the roots ``near`` (``(n,)``, m)
    starts from, :data:`NEAR_FACTOR` either side of each (:func:`outer_scale_root`; the
    same as :func:`cwproc.physics.root_search.replayed_root` scans first)."""
    return near[:, None] * np.array([1.0 / NEAR_FACTOR, 1.0, NEAR_FACTOR])


def fit_cells(
    setup: FitSetup,
    d: np.ndarray,
    var_raw: np.ndarray,
    near: np.ndarray | None = None,
    method1: bool = True,
    near_slope: np.ndarray | None = None,
    near_parts: dict | None = None,
) -> CellEstimates:
    """eps (methods 1 and 2), sigma_e, sigma_V^2 and L_V of every cell from D and the variance.

    The least squares of Smalikho (2020), eq. 4 over all valid lags with the cell's
    A-functions (:func:`cwproc.physics.structure_fit.fit_structure_function`); with a
    finite-outer-scale model, where a length exceeds :data:`INERTIAL_FRACTION` of the
    inertial L_V, the A-functions at the root of the variance condition
    (:func:`outer_scale_root`, :func:`_finite_scale_cells`). A pure function of
    ``(d, var_raw)`` given ``setup`` (the A-functions, tables, noise prediction, ...), so
    that :func:`cwproc.stages.epsilon.errors.covariance_errors` can differentiate it;
    ``near`` (that function's base roots, NaN where the finite-outer-scale fit was not
    used) fixes the cells of that fit and starts its root search there, from their slopes
    ``near_slope`` (the base's ``root_slope``) where given. ``method1=False`` leaves eps
    of method 1 (``e1``) NaN and ``a1`` the inertial tables' (the delta method uses
    neither). ``near_parts``: a dict the caller keeps over calls with the same ``near``
    (the delta method's), in which the parts of the variance condition that depend on
    ``L_V`` alone (:func:`scale_parts`) at the outer scales the root search near ``near``
    starts from (:func:`near_nodes`) are computed once and kept.
    """
    a1 = setup.tables.a1.copy() if method1 else setup.tables.a1
    a2 = setup.tables.a2.copy()
    shape = d.shape[:2]
    roots = _FiniteRoots.empty(shape)
    finite = setup.finite
    if finite is None or near is None:  # with both, every fit is redone below
        e1, efit, noise, fitted = _fit_lags(setup, d, a1, a2, method1)
        sigma2 = var_raw - np.nan_to_num(noise, nan=0.0) ** 2 + efit ** (2 / 3) * setup.loss
        l_v = _integral_scale(setup.c_model, sigma2, efit)
    if finite is not None:
        if near is None:
            need = np.isfinite(l_v) & (finite.longest > INERTIAL_FRACTION * l_v)
            need &= ~setup.exact
        else:
            need = np.isfinite(near)
        start = (near, near_slope, near_parts)
        _finite_scale_cells(setup, d, var_raw, need, start, (a1 if method1 else None, a2), roots)
        e1, efit, noise, fitted = _fit_lags(setup, d, a1, a2, method1)
        sigma2 = np.where(
            roots.used,
            (var_raw - np.nan_to_num(noise, nan=0.0) ** 2) / roots.passed_fraction,
            var_raw - np.nan_to_num(noise, nan=0.0) ** 2 + efit ** (2 / 3) * setup.loss,
        )
        l_v = _integral_scale(setup.c_model, sigma2, efit)
    return CellEstimates(
        a1=a1,
        a2=a2,
        e1=e1,
        efit=efit,
        noise=noise,
        fitted=fitted,
        sigma2=sigma2,
        l_v=l_v,
        too_small=roots.too_small,
        finite_used=roots.used,
        root=roots.root,
        root_slope=roots.slope,
    )


def _fit_lags(
    setup: FitSetup, d: np.ndarray, a1: np.ndarray, a2: np.ndarray, method1: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(e1, efit, noise, fitted)``: Smalikho (2020), eq. 4 with ``A_1`` (method 1, NaN
    without ``method1``) and with ``A_2`` (method 2, sigma_e fitted or predicted)."""
    prior, rel_se = setup.prior.predicted, setup.prior.rel_se
    e1 = np.full(d.shape[:2], np.nan)
    if method1:
        e1, _, _ = fit_structure_function(d, a1, setup.valid, prior, setup.d_cov, rel_se)
    efit, noise, fitted = fit_structure_function(d, a2, setup.valid, prior, setup.d_cov, rel_se)
    return e1, efit, noise, fitted


def _integral_scale(c_model: float, sigma2: np.ndarray, efit: np.ndarray) -> np.ndarray:
    """``L_V = c sigma_V^3 / eps`` (m, Banakh et al. (1999), eq. 19); NaN where
    ``sigma_V^2 <= 0``."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(sigma2 > 0, c_model * np.abs(sigma2) ** 1.5 / efit, np.nan)


@dataclass(frozen=True)
class _FiniteRoots:
    """``(time, height)`` outcome of the variance condition per cell (:func:`fit_cells`):
    its root L_V (m) and the residual's slope there, whether the finite fit was used,
    whether even the smallest node gave too much variance, and the passed fraction of
    sigma_V^2 at the root."""

    root: np.ndarray
    slope: np.ndarray
    used: np.ndarray
    too_small: np.ndarray
    passed_fraction: np.ndarray

    @classmethod
    def empty(cls, shape: tuple[int, ...]) -> _FiniteRoots:
        nan = functools.partial(np.full, shape, np.nan)
        no = functools.partial(np.zeros, shape, dtype=bool)
        return cls(nan(), nan(), no(), no(), nan())


def _finite_scale_cells(
    setup: FitSetup,
    d: np.ndarray,
    var_raw: np.ndarray,
    need: np.ndarray,
    start: tuple[np.ndarray | None, np.ndarray | None, dict | None],
    a_functions: tuple[np.ndarray | None, np.ndarray],
    roots: _FiniteRoots,
) -> None:
    """Solve the variance condition of the cells ``need``, one table configuration at a
    time, and put the model's A-functions at the root into ``a_functions`` (``(a1, a2)``,
    in place; ``a1`` None: not wanted) and the outcome into ``roots``; ``start``:
    ``(near, near_slope, near_parts)`` of :func:`fit_cells`."""
    finite, sector = setup.finite, setup.tables.sector
    near, near_slope, near_parts = start
    a1, a2 = a_functions
    for key, (rows, _) in setup.tables.groups.items():  # one table per configuration
        cells_of = _group_cells(setup, need, key, rows, near_parts if near is not None else None)
        if cells_of is None:
            continue
        ti, hi_, cells, passed, static = cells_of
        table = setup.cell_tables[key][0]
        root, use, below = np.empty(ti.size), np.empty(ti.size, bool), np.empty(ti.size, bool)
        for lo in range(0, ti.size, ROOT_CELLS):  # bounded working memory
            at = slice(lo, lo + ROOT_CELLS)
            t_, h_ = ti[at], hi_[at]
            known = None
            if near is not None and near_parts is not None:
                if (key, lo) not in near_parts:
                    l_near = near_nodes(near[t_, h_])
                    parts = scale_parts(
                        table, cells[at], static[0][at], finite.scale_grid, passed[at], l_near
                    )
                    near_parts[(key, lo)] = (l_near, *parts)
                known = near_parts[(key, lo)]
            sec, valid, prior, d_cov = (None if c is None else c[at] for c in static)
            chunk = (cells[at], passed[at], sec, d[t_, h_], valid, var_raw[t_, h_], prior, d_cov)
            residual_of = functools.partial(
                _cells_residual,
                table=table,
                finite=finite,
                chunk=chunk,
                rel_se=setup.prior.rel_se,
                known=known,
            )
            root[at], use[at], below[at], roots.slope[t_, h_] = outer_scale_root(
                residual_of,
                t_.size,
                finite.nodes,
                None if near is None else near[t_, h_],
                None if near_slope is None else near_slope[t_, h_],
            )
        if np.any(use):
            tu, hu = ti[use], hi_[use]
            g1, g2 = table.evaluate(root[use][:, None], cells[use], a1=a1 is not None)
            if a1 is not None:
                a1[tu, hu] = g1[:, 0]
            a2[tu, hu] = g2[:, 0] * sector[tu, hu]
            roots.used[tu, hu] = True
            roots.root[tu, hu] = root[use]
            scale_grid = finite.scale_grid
            through = interp_log_scale(scale_grid, passed[use], root[use][:, None])[:, 0]
            total = np.interp(np.log(root[use]), np.log(scale_grid), finite.full_var)
            roots.passed_fraction[tu, hu] = through / total
        roots.too_small[ti[below], hi_[below]] = True


def _group_cells(
    setup: FitSetup, need: np.ndarray, key: tuple, rows: np.ndarray, kept: dict | None
) -> tuple | None:
    """``(ti, hi, table rows, passed, (sector, valid, prior, d_cov))`` of the cells
    ``need`` of the configuration ``key`` (blocks ``rows``) for :func:`_finite_scale_cells`,
    what does not depend on the statistics gathered once; None without such cells.
    ``kept``: the ``near_parts`` of :func:`fit_cells` (whose ``need`` is the same at every
    call), where they are kept."""
    if kept is not None and ("cells", key) in kept:
        return kept[("cells", key)]
    ti, hi_ = np.nonzero(need & rows[:, None])
    if ti.size == 0:
        return None
    cells = setup.cell_tables[key][1][ti] * need.shape[1] + hi_
    d_cov = setup.d_cov
    static = (
        setup.tables.sector[ti, hi_],
        setup.valid[ti, hi_],
        setup.prior.predicted[ti, hi_][:, None],
        None if d_cov is None else d_cov[ti, hi_],
    )
    out = (ti, hi_, cells, setup.finite.passed[ti, hi_], static)
    if kept is not None:
        kept[("cells", key)] = out
    return out


def _remembered(memo: FitMemo | None, key: tuple, compute: Callable[[], np.ndarray]) -> np.ndarray:
    """``compute()``, kept in ``memo`` (:meth:`FitMemo.remembered`) if there is one."""
    return compute() if memo is None else memo.remembered(key, compute)


#: nodes of ``mu`` of :func:`transport_loss` (linear interpolation in between; beyond
#: the last, the loss per cell is computed at its own ``mu``)
TRANSPORT_MU_NODES = np.array([0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0])
#: geometric ratio of the ``dy`` nodes of :func:`transport_loss`
TRANSPORT_DY_RATIO = 1.4


def transport_loss(
    probe: Any, cells: Cells, options: TableOptions, memo: FitMemo | None
) -> np.ndarray:
    """``(time, height)`` variance lost to the transport during each ray, per eps^(2/3).

    :func:`cwproc.physics.probe_variance.segment_loss` (a swept ray's segment ``dy (e_scan
    - mu e_wind)`` beyond its sweep; a step-stare ray's ``d mu dy e_wind``, ``d =
    options.dwell``) on :data:`TRANSPORT_MU_NODES` and geometric ``dy`` nodes (ratio
    :data:`TRANSPORT_DY_RATIO`; a pulsed probe's range weighting does not depend on the
    range), linear in ``mu`` and, as ``loss dy^(-2/3)`` (its inertial scaling), in ``log
    dy`` in between (within 0.5 % of direct evaluation, or 0.1 m^(2/3) where the loss
    is small; tested). Without it the passed variance
    of a 72-ray continuous scan at ``mu = 3`` was 6-8.5 % above the exact variance of
    ``V_r`` (``../shared/reference/exact-D-72ray-mu3.md``; with it 0.4-0.7 % below), so
    ``sigma_V^2`` and ``L_V`` were low and eps +8-20 % high. Zero for cw probes (whose
    range weighting depends on the range and whose transverse averaging is not a
    segment) and instantaneous step-stare rays.
    """
    shape = cells.dy.shape
    swept, dwell = bool(options.swept), float(options.dwell)
    dy = cells.dy.ravel()
    ok = np.isfinite(dy) & (dy > 0)
    if is_cw_probe(probe) or (not swept and dwell == 0.0) or not ok.any():
        return np.zeros(shape)
    lo, hi = float(dy[ok].min()), float(dy[ok].max())
    n_dy = max(2, int(np.ceil(np.log(hi / lo) / np.log(TRANSPORT_DY_RATIO))) + 1)
    dy_nodes = np.geomspace(lo, hi, n_dy) if hi > lo else np.array([lo, lo * TRANSPORT_DY_RATIO])
    phi, range_m = float(np.nanmedian(cells.phi)), float(np.nanmedian(cells.range_m))
    mu = cells.mu_eval.ravel()
    nodes = TRANSPORT_MU_NODES
    if np.nanmax(mu, initial=0.0) > nodes[-1]:
        nodes = np.append(nodes, np.nanmax(mu))
    table = _remembered(
        memo,
        ("transport", swept, dwell, phi, range_m, nodes.tobytes(), dy_nodes),
        lambda: (
            dy_nodes[:, None] ** (-2.0 / 3.0)
            * segment_loss(
                probe,
                dy_nodes,
                np.full(dy_nodes.size, range_m),
                nodes,
                phi_deg=phi,
                swept=swept,
                dwell=dwell,
            )
        ),
    )
    x = np.log(np.where(ok, dy, lo))
    j = np.clip(np.searchsorted(np.log(dy_nodes), x, side="right") - 1, 0, dy_nodes.size - 2)
    wj = np.clip((x - np.log(dy_nodes[j])) / np.log(dy_nodes[j + 1] / dy_nodes[j]), 0.0, 1.0)
    k = np.clip(np.searchsorted(nodes, mu, side="right") - 1, 0, nodes.size - 2)
    wk = np.clip((mu - nodes[k]) / (nodes[k + 1] - nodes[k]), 0.0, 1.0)
    out = (1.0 - wj) * ((1.0 - wk) * table[j, k] + wk * table[j, k + 1]) + wj * (
        (1.0 - wk) * table[j + 1, k] + wk * table[j + 1, k + 1]
    )
    return np.where(ok, out * np.where(ok, dy, 0.0) ** (2.0 / 3.0), 0.0).reshape(shape)


def fit_setup(
    cells: Cells,
    tables: CellTables,
    *,
    probe: Any,
    model: str,
    options: TableOptions,
    valid: np.ndarray,
    exact: np.ndarray,
    prior: NoisePrior,
    n_outer_scales: int,
    cov: np.ndarray | None = None,
    memo: FitMemo | None = None,
) -> FitSetup:
    """Everything :func:`fit_cells` needs besides ``D`` and the variance of ``V'_L``.

    The A-functions of the cells (``tables``, of
    :func:`cwproc.stages.epsilon.atable_fit.cell_a_functions`), the valid lags, the
    predicted noise (``prior``), the inertial averaging loss per distinct ``(dy, range)``
    (:func:`cwproc.physics.probe_variance.averaging_loss`) and the transport during the
    ray (:func:`transport_loss`), the coefficient ``c`` of ``L_V = c sigma_V^3 / eps``
    (Banakh et al. (1999), eq. 19), the cw cells of the exact model (``exact``) and, for
    finite-outer-scale models, the inputs of the variance condition
    (:func:`finite_scale_inputs`) and the model's tables at each group's cells
    (:meth:`cwproc.physics.atable_interp.ATable.at_cells`). ``cov``: the covariance of
    the block means of ``(D_L(1..L), variance)``
    (:func:`cwproc.stages.epsilon.cells.statistics_covariance`); its ``D_L`` block decides
    where the noise is fitted (:func:`cwproc.physics.structure_fit.fit_structure_function`).
    ``memo`` keeps what depends on the distinct (dy, range) pairs only (the averaging
    loss, the passed variance) for the next group of blocks of the same probe and model,
    which has the same pairs where :func:`cwproc.stages.epsilon.block_groups` splits a day.
    """
    dy = cells.dy
    a2 = few_ray_inertial_a2(cells, options, tables.a2, tables.sector)
    # the loss depends on (dy, range) only: compute it once per distinct pair
    # step-stare rays are not swept: no transverse averaging in the variance (eq. 20)
    dy_filter = dy if options.swept else np.where(np.isfinite(dy), 0.0, np.nan)
    pairs_dr = np.stack([np.round(dy_filter, 6).ravel(), np.round(cells.range_m, 6).ravel()], 1)
    uniq, inverse = np.unique(np.nan_to_num(pairs_dr, nan=-1.0), axis=0, return_inverse=True)
    loss_u = _remembered(
        memo,
        ("loss", uniq),
        lambda: np.where(
            uniq[:, 0] >= 0, averaging_loss(probe, np.abs(uniq[:, 0]), np.abs(uniq[:, 1])), np.nan
        ),
    )
    loss = loss_u[inverse.ravel()].reshape(dy.shape)
    # ... and the transport during the ray, per cell (its mu)
    carried = transport_loss(probe, cells, options, memo)
    loss = loss + carried
    finite = None
    if model != "inertial" and tables.groups:
        finite = finite_scale_inputs(
            probe, model, options, uniq, inverse, cells, n_outer_scales, memo
        )
        finite.passed[...] -= carried[..., None] * carried_scale_factor(
            cells, options, finite.scale_grid, model
        )
    lags = np.arange(1, cells.d.shape[2] + 1, dtype=float)
    return FitSetup(
        tables=dataclasses.replace(tables, a2=a2),
        valid=valid,
        prior=prior,
        d_cov=None if cov is None else cov[..., :-1, :-1],
        loss=loss,
        c_model=spectra.integral_scale_coefficient("exponential" if model == "inertial" else model),
        cell_tables={  # the model's tables at each group's cells (rows x heights)
            key: (_sector_cell_table(group_tables, lags, cells, rows), np.cumsum(rows) - 1)
            for key, (rows, group_tables) in tables.groups.items()
            if finite is not None
        },
        exact=exact,
        finite=finite,
    )


def _sector_cell_table(tables: tuple, lags: np.ndarray, cells: Cells, rows: np.ndarray) -> Any:
    """The finite table at the cells ``rows x heights`` with its own sector ratio.

    :meth:`cwproc.physics.atable_interp.ATable.at_cells` of ``tables[1]``, its ``A_2`` at
    every outer-scale node, for sectors and gaps (:attr:`Cells.partial`), multiplied by
    :func:`outer_scale_sector_factor` (the sector ratio of the outer scale over the
    inertial one that :func:`fit_cells` applies); less the share of ``D(l)`` the block-mean
    VAD wind takes times ``sigma_V^2 / eps^(2/3)`` of the node: :func:`sector_removed_d`
    for sectors and gaps (up to ``MAX_SECTOR_RAYS`` rays per scan), :func:`circle_removed_d`
    for full circles of steps of at least :data:`COARSE_STEP_DEG` (72 rays: from the circle
    of ``MAX_SECTOR_RAYS`` rays).
    """
    height = np.tile(cells.height, rows.sum())
    mu = cells.mu_eval[rows].ravel()
    table = tables[1].at_cells(lags, height, mu)
    weights = cells.weights[rows].reshape(-1, cells.weights.shape[-1])
    n_h = cells.height.size
    dtheta = np.repeat(cells.dtheta[rows], n_h)
    partial = cells.partial[rows].ravel()
    part = np.nonzero(partial)[0]
    log_a2 = table.log_a2.copy()
    # the outer scale's own ratio over the azimuths of each lag's pairs (uniform weights:
    # 1 by construction). Partial circles, and full circles of coarse scans, whose pairs
    # do not wrap (lag l lacks l of M positions); dense full circles (M > 72: at most 2-3 %
    # of the positions, at lags where the outer scale barely changes the node ratio) keep
    # the inertial ratio alone, which saves most of the stage's time on a day of them
    coarse = np.nonzero(partial | (dtheta >= COARSE_STEP_DEG))[0]
    if coarse.size:
        lag_weights = cells.lag_weights[rows].reshape(-1, *cells.lag_weights.shape[-2:])
        factor = outer_scale_sector_factor(
            tables, lags, height[coarse], mu[coarse], lag_weights[coarse]
        )
        few_ray = few_ray_circles(tables, partial[coarse], dtheta[coarse])
        if few_ray.any():
            at = coarse[few_ray]
            cell_range = np.asarray(cells.range_m)[rows].ravel()[at]
            circle_a2 = np.exp(log_a2[at])
            factor[few_ray] = few_ray_factor(
                tables, lags, height[at], mu[at], lag_weights[at], cell_range, circle_a2
            )
        log_a2[coarse] += np.log(factor)
    # the block-mean VAD fit also takes part of D(l)
    scans = np.repeat(cells.scans[rows], n_h)
    scans = np.where(np.isfinite(scans) & (scans >= 1), scans, 1.0)
    interval = np.repeat(cells.interval[rows], n_h)
    nodes = tables[1].outer_scales_m
    ratio = cells.radius[rows].ravel()[:, None] / nodes[None, :]
    phi, model = float(np.nanmedian(cells.phi)), tables[1].model
    removed = np.zeros(log_a2.shape)
    if part.size:
        removed[part] = sector_removed_d(
            weights[part],
            np.radians(dtheta[part]),
            lags.size,
            ratio[part],
            mu[part],
            interval[part],
            scans[part],
            phi,
            model,
        )
    # full circles of at most 72 rays (denser: the removal's share of the intercept falls
    # as the lag angle^(4/3), about 3 % of 2 sigma_e^2 at 180 rays against 4 % at 72, and
    # its 0.3 s would take the 180-ray day past 1 s)
    circle = np.nonzero(~partial & (dtheta >= COARSE_STEP_DEG))[0]
    if circle.size:
        # the field's transport between the scans: the measured mu less its turbulent bias,
        # taken in as the measured wind rises above that scatter (transport_weight)
        var, v_s = cells.var_raw[rows].ravel()[circle], cells.v_s[rows].ravel()[circle]
        rest = mean_removed_share(ratio[circle], phi, model, 0.0)
        setting = (mu[circle], rest, var, v_s, scans[circle], phi)
        mu_t, weight = transport_mu(*setting), transport_weight(*setting)

        def circle_removal(at: np.ndarray, transport: np.ndarray) -> np.ndarray:
            c = circle[at]
            return circle_removed_d(
                np.radians(dtheta[c]),
                lags.size,
                ratio[c],
                transport,
                interval[c],
                scans[c],
                phi,
                model,
                dense_reference=stored_dense_grid,
            )

        # each part where it counts: most cells are wholly carried or wholly at rest
        moving = np.nonzero((weight > 0.0).any(axis=-1))[0]
        resting = np.nonzero((weight < 1.0).any(axis=-1))[0]
        if moving.size:
            removed[circle[moving]] = weight[moving, :, None] * circle_removal(moving, mu_t[moving])
        if resting.size:
            removed[circle[resting]] += (1.0 - weight[resting, :, None]) * circle_removal(
                resting, np.zeros_like(mu_t[resting])
            )
    full = np.array([spectra.variance_per_eps23(model, x) for x in nodes])
    circle = np.exp(log_a2)
    a2 = circle - removed * full[None, :, None]
    log_a2 = np.log(np.maximum(a2, np.multiply(1e-3, circle, out=circle), out=a2), out=a2)
    return dataclasses.replace(table, log_a2=log_a2)
