"""The A-functions of each cell from the A-tables: methods 1 and 2 of Smalikho (2020).

``A_1 = A_perp`` (method 1) and ``A_2`` of Smalikho (2020), eq. 15 (method 2) of the
probe at each block and height, interpolated from the cached tables of
:mod:`cwproc.physics.atable` (one per elevation and azimuth step); ``A_2`` averaged over
the azimuths of the pairs present (sectors and gaps).
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from cwproc.physics.atable import HEIGHT_RATIO
from cwproc.physics.atable_interp import N_BINS
from cwproc.physics.probe_lengths import FALLBACK_PRF_HZ, dwell_fraction, ray_dwell_s
from cwproc.stages.epsilon.cells import Cells
from cwproc.tables.atable import get_a_table

#: cells (block, height) whose A-functions or passed variances are evaluated at once:
#: the evaluations hold a few kB per cell, so a day of blocks is done in pieces
EVALUATION_CELLS = 2048


def evaluate_table(
    table: Any, lags: np.ndarray, height: np.ndarray, mu: np.ndarray, outer: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """``(A_1, A_2)`` (m^(2/3)) of ``table`` in the broadcast shape of the arguments.

    :meth:`cwproc.physics.atable_interp.ATable.evaluate` on the flattened arguments in
    pieces of bounded memory; ``outer``: ``L_V`` (m), ``None`` for inertial tables.
    """
    args = [lags, height, mu] + ([] if outer is None else [outer])
    b = np.broadcast_arrays(*[np.asarray(x, dtype=float) for x in args])
    shape = b[0].shape
    flat = [x.ravel() for x in b]
    a1 = np.empty(flat[0].size)
    a2 = np.empty(flat[0].size)
    step = EVALUATION_CELLS * 8  # values per call: bounded working memory of the table
    for start in range(0, a1.size, step):
        part = [x[start : start + step] for x in flat]
        a1[start : start + step], a2[start : start + step] = table.evaluate(
            part[0], part[1], part[2], outer_scale_m=None if outer is None else part[3]
        )
    return a1.reshape(shape), a2.reshape(shape)


#: the A-table's default height range (m) and the smallest height it is widened to
DEFAULT_HEIGHT_RANGE_M = (10.0, 3000.0)

MIN_TABLE_HEIGHT_M = 1.0


def table_height_range(
    height_m: np.ndarray, default: tuple[float, float] = DEFAULT_HEIGHT_RANGE_M
) -> tuple[float, float]:
    """Height range (m) of the A-table: the default, widened to cover the data's heights.

    The default range is extended downwards and upwards in steps of ``HEIGHT_RATIO^4``
    (about x2.07, four table nodes) until it holds every finite height at or above
    :data:`MIN_TABLE_HEIGHT_M`, so that few distinct tables (cache files) arise; each
    step adds four height nodes, about 12 % of the default table's build time.

    Parameters
    ----------
    height_m : numpy.ndarray
        Heights of the product (m).
    default : (float, float)
        Range used when every height lies inside it.
    """
    h = np.asarray(height_m, dtype=float)
    h = h[np.isfinite(h) & (h >= MIN_TABLE_HEIGHT_M)]
    lo, hi = (float(v) for v in default)
    if h.size == 0:
        return lo, hi
    step = HEIGHT_RATIO**4
    if h.min() < lo:
        lo = lo / step ** math.ceil(math.log(lo / h.min()) / math.log(step))
    if h.max() > hi:
        hi = hi * step ** math.ceil(math.log(h.max() / hi) / math.log(step))
    return lo, hi


@dataclass(frozen=True)
class TableOptions:
    """The A-table settings of a dataset (:func:`table_options_for`): the keyword
    arguments of :func:`cwproc.tables.atable.get_a_table` besides the scan geometry,
    with its defaults.

    Attributes
    ----------
    height_range_m : tuple of float
        Heights the tables cover (m).
    swept : bool
        Swept rays (continuous scans) or step-stare rays.
    dwell : float
        Dwell fraction of step-stare rays (0: instantaneous).
    mu_max : float
        Largest ``mu = U / V_s`` of the tables.
    outer_scale_range_m : tuple of float
        L_V range (m) of the finite-outer-scale tables and fits.
    geometry : str or None
        Pair geometry (None: the tables' default, the exact two-beam one).
    cache_dir : str or os.PathLike or None
        Where tables are cached (None: the table store's default).
    """

    height_range_m: tuple[float, float]
    swept: bool = True
    dwell: float = 0.0
    mu_max: float = 10.0
    outer_scale_range_m: tuple[float, float] = (10.0, 3000.0)
    geometry: str | None = None
    cache_dir: str | os.PathLike | None = None

    def table_kwargs(self, *, finite: bool) -> dict[str, Any]:
        """The keyword arguments of :func:`cwproc.tables.atable.get_a_table` (an inertial
        table has no outer-scale range)."""
        kwargs = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        if not finite:
            del kwargs["outer_scale_range_m"]
        return kwargs


def a_tables(
    probe: Any, phi: float, dtheta: float, n_lags: int, model: str, options: TableOptions
) -> tuple:
    """The inertial A-table and, for finite-outer-scale models, the model's table."""
    inertial = get_a_table(
        probe,
        phi_deg=phi,
        delta_theta_deg=dtheta,
        n_lags=n_lags,
        model="inertial",
        **options.table_kwargs(finite=False),
    )
    if model == "inertial":
        return inertial, None
    finite = get_a_table(
        probe,
        phi_deg=phi,
        delta_theta_deg=dtheta,
        n_lags=n_lags,
        model=model,
        **options.table_kwargs(finite=True),
    )
    return inertial, finite


def sector_evaluate(
    table: Any, lags: np.ndarray, height: np.ndarray, mu: np.ndarray, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A_1, A_2, ratio)`` of an inertial table for blocks ``(t, h, lag)``.

    ``A_2`` averaged over the azimuths of the pairs present (``weights``, ``(t, h, N_BINS)``
    or per lag ``(t, h, lag, N_BINS)``; NaN rows: the full circle) and ``ratio`` = that
    over the full-circle ``A_2`` (1 where no weights): the same ratio scales the
    finite-outer-scale ``A_2`` (whose tables carry no nodes).
    """
    a1, a2_full = evaluate_table(
        table, lags[None, None, :], height[None, :, None], mu[:, :, None], None
    )
    if weights.ndim == 3:
        weights = np.broadcast_to(weights[:, :, None, :], (*weights.shape[:2], lags.size, N_BINS))
    known = np.all(np.isfinite(weights), axis=(-2, -1))
    ratio = np.ones(a2_full.shape)
    # height by height: each piece interpolates the table's azimuth nodes in height at
    # its own few heights (in block order, every piece took all the heights of a day)
    all_hi, all_ti = np.nonzero(known.T)
    for start in range(0, all_ti.size, EVALUATION_CELLS):  # bounded working memory
        ti = all_ti[start : start + EVALUATION_CELLS]
        hi = all_hi[start : start + EVALUATION_CELLS]
        _, part = table.evaluate(
            np.broadcast_to(lags[None, :], (ti.size, lags.size)).ravel(),
            np.repeat(height[hi], lags.size),
            np.repeat(mu[ti, hi], lags.size),
            weights=weights[ti, hi].reshape(-1, N_BINS),
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio[ti, hi] = part.reshape(ti.size, lags.size) / a2_full[ti, hi]
    return a1, a2_full * ratio, ratio


#: (point, outer-scale node) pairs of :func:`outer_scale_sector_factor` held at once
#: (the per-node ratios of a chunk: 36 nodes x 8 bytes x 4 mu neighbours each)
SCALE_POINTS = 32768


def outer_scale_sector_factor(
    tables: tuple, lags: np.ndarray, height: np.ndarray, mu: np.ndarray, weights: np.ndarray
) -> np.ndarray:
    """``(cells, nL, n_lag)``: the sector ratio of ``A_2`` with an outer scale over the inertial.

    At each outer-scale node of the finite table (``tables = (inertial, finite)``), the
    average of ``A_2`` over the azimuths of the pairs present (``weights``, ``(cells,
    N_BINS)``, or per lag ``(cells, n_lag, N_BINS)``) relative to its circle mean is the
    inertial table's per-node ratio times
    :meth:`cwproc.physics.atable_interp.ATable.scale_ratio`, normalised to a circle mean
    of 1 (away from the reference height the product alone is not); this is that over
    the inertial sector ratio of :func:`sector_evaluate` (1 for unknown weights and
    tables without ``scale_bins``). ``height`` (m) and ``mu`` per cell.
    """
    inertial, finite = tables
    scales = finite.outer_scales_m
    out = np.ones((height.size, scales.size, lags.size))
    if finite.scale_bins is None:
        return out
    if weights.ndim == 2:
        weights = np.broadcast_to(weights[:, None, :], (weights.shape[0], lags.size, N_BINS))
    known = np.nonzero(np.all(np.isfinite(weights), axis=(-2, -1)))[0]
    lag_k = np.broadcast_to(lags[None, :], (known.size, lags.size)).ravel()
    h_k, mu_k = np.repeat(height[known], lags.size), np.repeat(mu[known], lags.size)
    w_k = weights[known].reshape(-1, N_BINS)
    # A_2(w) / A_2(circle) = sum(r w): the inertial node ratio r (once), and per node of
    # L_V the outer scale's factor on it
    ratio = np.empty(w_k.shape)
    by_height = np.argsort(h_k, kind="stable")  # few heights a piece (sector_evaluate)
    for start in range(0, lag_k.size, SCALE_POINTS // 4):  # bounded working memory
        q = by_height[start : start + SCALE_POINTS // 4]
        ratio[q] = inertial.node_ratio(lag_k[q], h_k[q], mu_k[q])
    weighted, circle = ratio * w_k, ratio / N_BINS
    base = np.sum(weighted, axis=-1)
    chunk = max(1, SCALE_POINTS // scales.size)  # points at once: bounded working memory
    factor = np.empty((lag_k.size, scales.size))
    by_stencil = np.lexsort((mu_k, lag_k))  # chunks of few (lag, mu stencil) groups
    for start in range(0, lag_k.size, chunk):
        q = by_stencil[start : start + chunk]
        sums = finite.scale_ratio_sums(
            lag_k[q],
            h_k[q],
            mu_k[q],
            scales,
            np.stack([weighted[q], circle[q]], axis=1),
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            factor[q] = sums[..., 0] / (base[q, None] * sums[..., 1])
    out[known] = np.moveaxis(factor.reshape(known.size, lags.size, scales.size), 1, 2)
    return np.where(np.isfinite(out) & (out > 0), out, 1.0)


def table_options_for(
    sf: xr.Dataset, table_options: dict | None, prf_hz: float | None = None
) -> TableOptions:
    """The A-table settings of ``sf`` (:class:`TableOptions`).

    ``table_options`` (keyword arguments of :func:`cwproc.tables.atable.get_a_table`)
    completed with the height range of the data (:func:`table_height_range`), whether
    the rays are swept (``swept_rays``) and, for step-stare rays, their dwell fraction
    (:func:`stare_dwell`).
    """
    options = dict(table_options or {})
    if "height_range_m" not in options:
        options["height_range_m"] = table_height_range(sf["height"].values)
    options.setdefault("swept", bool(int(sf.attrs.get("swept_rays", 1))))
    if not options["swept"]:
        options.setdefault("dwell", stare_dwell(sf, prf_hz)[1])
    return TableOptions(**options)


def stare_dwell(sf: xr.Dataset, prf_hz: float | None = None) -> tuple[float, float, float]:
    """``(T_d, d, tau)``: dwell (s), dwell fraction and ray period (s) of the step-stare rays.

    ``T_d`` = pulses per ray (``pulses_per_ray``, the Stream Line header) / ``prf_hz``
    (:func:`cwproc.physics.probe_lengths.ray_dwell_s`; None: the Stream Line's 15 kHz),
    ``tau`` the median over the blocks of ``scan_period dtheta / 360`` (the period of
    ``V_s = 2 pi R' / T_scan = dy / tau``, :mod:`cwproc.stages.epsilon.cells`), ``d =
    T_d / tau`` in ``[0, 1]`` (:func:`cwproc.physics.probe_lengths.dwell_fraction`; 0
    and ``T_d`` NaN when the pulses per ray are unknown: instantaneous rays).
    """
    rate = FALLBACK_PRF_HZ if prf_hz is None else float(prf_hz)
    dwell = ray_dwell_s(sf.attrs.get("pulses_per_ray"), rate)
    tau = np.nan
    if "scan_period" in sf and "azimuth_step" in sf:
        with np.errstate(invalid="ignore"):
            per_block = sf["scan_period"].values.astype(float) * (
                sf["azimuth_step"].values.astype(float) / 360.0
            )
        per_block = per_block[np.isfinite(per_block) & (per_block > 0)]
        tau = float(np.median(per_block)) if per_block.size else np.nan
    fraction = dwell_fraction(dwell, tau)
    return (np.nan if dwell is None else float(dwell)), fraction, tau


def cell_a_functions(probe: Any, cells: Cells, model: str, options: TableOptions) -> tuple:
    """``(A_1, A_2, sector, groups)`` of every cell from the inertial A-tables.

    One pair of tables per (elevation, azimuth step) (:func:`a_tables`), evaluated for
    all blocks at once: ``A_1 = A_perp`` (method 1) and ``A_2`` of Smalikho (2020), eq.
    15 (method 2), averaged over the azimuths of the pairs present; ``sector`` is that
    average over the full-circle ``A_2`` (:func:`sector_evaluate`). ``groups`` maps
    ``(phi, dtheta)`` to ``(rows, tables)``. NaN A-functions with fewer than two lags.
    """
    n_l = cells.n_lags
    lags = np.arange(1, n_l + 1, dtype=float)
    a1 = np.full(cells.d.shape, np.nan)
    a2 = np.full(cells.d.shape, np.nan)
    key_phi = np.round(cells.phi, 3)
    key_dth = np.round(cells.dtheta, 4)
    groups = {}
    # sectors and gaps: A_2 over the azimuths present relative to the full circle
    sector = np.ones(cells.d.shape)
    if n_l >= 2:
        for p, q in {(p, q) for p, q in zip(key_phi, key_dth, strict=True) if np.isfinite(p + q)}:
            rows = (key_phi == p) & (key_dth == q)
            groups[(p, q)] = (rows, a_tables(probe, float(p), float(q), n_l, model, options))
            a1[rows], a2[rows], sector[rows] = sector_evaluate(
                groups[(p, q)][1][0],
                lags,
                cells.height,
                cells.mu_eval[rows],
                cells.lag_weights[rows],
            )
    return a1, a2, sector, groups
