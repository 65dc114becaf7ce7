"""cw cells: the exact lag model of the two beams (Banakh et al. (1999), eqs. 15-17).

A focused cw probe is hundreds of metres long, so the shape of ``D_L`` over the lags
fixes ``L_V``: :func:`fit_exact_cells` fits ``2 sigma_V^2 [b_0 - b_l] + 2 sigma_e^2``
(:class:`cwproc.physics.exact_lag.ExactLagModel`) and takes ``eps = c sigma_V^3 / L_V``
(Banakh et al. (1999), eq. 19).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from cwproc.physics.exact_lag import (
    exact_lag_model_cached,
    fit_correlation_shape,
    is_cw_probe,
    running_nanmedian,
    variance_root,
)
from cwproc.physics.structure_fit import fit_structure_function
from cwproc.stages.epsilon.atable_fit import TableOptions, evaluate_table
from cwproc.stages.epsilon.cells import Cells
from cwproc.stages.epsilon.records import CellEstimates, FitSetup

#: blocks over which the cw fit pools the noise variance (median), see :func:`fit_exact_cells`
NOISE_WINDOW_BLOCKS = 7
#: mu = U/V_s up to which cw cells use :class:`cwproc.physics.exact_lag.ExactLagModel`
#: (transport neglected; cw lidars scan fast: mu <= 0.09 for the lidar of Banakh et al.
#: (1999), about 0.01 for a ZephIR)
CW_EXACT_MU_MAX = 0.1


def fit_exact_cells(
    probe: Any,
    cells: Cells,
    valid: np.ndarray,
    exact: np.ndarray,
    model: str,
    c_model: float,
    fit_noise: bool,
    noise_window: int,
) -> dict[str, np.ndarray]:
    """eps, sigma_e, sigma_V^2, L_V of the cw cells ``exact`` from the exact lag model.

    :class:`cwproc.physics.exact_lag.ExactLagModel`, one per (range, elevation, step).

    Shape fit (:func:`cwproc.physics.exact_lag.fit_correlation_shape`) gives ``sigma_fit^2``
    and ``L_fit``, so ``eps = c sigma_fit^3 / L_fit`` (Banakh et al. (1999), eq. 19), and with
    ``fit_noise`` sigma_e from the fit's intercept ``2 sigma_e^2`` (else 0). The variance
    of ``V'_L`` minus sigma_e^2 is ``sigma_V^2 (b_0 - tr(H B_D)/(N M sigma_V^2))`` with
    ``sigma_V^2 = (eps L_V / c)^(2/3)``, solved for L_V
    (:func:`cwproc.physics.exact_lag.variance_root`).
    """
    d, var_raw, n_scans, range_m = cells.d, cells.var_raw, cells.scans, cells.range_m
    phi, dtheta = cells.phi, cells.dtheta
    n_t, n_h, n_l = d.shape
    out = {
        k: np.full((n_t, n_h), np.nan)
        for k in ("epsilon", "noise_std", "velocity_variance", "integral_scale")
    }
    out["below_range"] = np.zeros((n_t, n_h), dtype=bool)
    out["structure_function_model"] = np.full(d.shape, np.nan)
    phi_b = np.broadcast_to(np.round(phi, 3)[:, None], (n_t, n_h))
    dth_b = np.broadcast_to(np.round(dtheta, 4)[:, None], (n_t, n_h))
    keys = np.stack([np.round(range_m, 3), phi_b, dth_b], axis=-1)
    n_eff = np.where(np.isfinite(n_scans) & (n_scans >= 1), n_scans, 1.0)
    for key in np.unique(keys[exact], axis=0):  # one exact model per configuration
        ti, hi_ = np.nonzero(exact & np.all(keys == key, axis=-1))
        lm = exact_lag_model_cached(
            probe, float(key[0]), float(key[1]), float(key[2]), int(n_l), model
        )
        dc, vc = d[ti, hi_], valid[ti, hi_]
        s2, l_fit, nv = fit_correlation_shape(dc, lm.structure, lm.scales, vc, noise=fit_noise)
        if fit_noise and noise_window > 1 and ti.size > 1:
            # the noise of neighbouring blocks, pooled: 2 parameters per block, not 3
            pooled = running_nanmedian(nv, ti, noise_window)
            s2_p, l_p, _ = fit_correlation_shape(
                dc - 2.0 * pooled[:, None], lm.structure, lm.scales, vc
            )
            ok = np.isfinite(s2_p) & np.isfinite(pooled)
            s2, l_fit = np.where(ok, s2_p, s2), np.where(ok, l_p, l_fit)
            nv = np.where(ok, pooled, nv)
        with np.errstate(invalid="ignore", divide="ignore"):
            eps = c_model * s2**1.5 / l_fit
        pos = np.interp(
            np.log(np.nan_to_num(l_fit, nan=lm.scales[0])),
            np.log(lm.scales),
            np.arange(lm.scales.size),
        )
        shape = np.stack(
            [np.interp(pos, np.arange(lm.scales.size), lm.structure[:, j]) for j in range(n_l)],
            axis=-1,
        )
        noise = np.sqrt(nv)
        measured = var_raw[ti, hi_] - noise**2
        scale = variance_root(eps, measured, lm, n_eff[ti], c_model)
        with np.errstate(invalid="ignore"):
            sig2 = (eps * scale / c_model) ** (2 / 3)
        out["epsilon"][ti, hi_] = eps
        out["noise_std"][ti, hi_] = noise
        out["velocity_variance"][ti, hi_] = sig2
        out["integral_scale"][ti, hi_] = scale
        out["below_range"][ti, hi_] = l_fit <= lm.scales[0] * (1.0 + 1e-9)
        out["structure_function_model"][ti, hi_] = s2[:, None] * shape + 2.0 * nv[:, None]
    return out


def exact_cells(probe: Any, cells: Cells, model: str) -> np.ndarray:
    """``(time, height)`` cells of the exact model: cw probe, finite outer scale, small mu.

    Wind transport is neglected by :class:`cwproc.physics.exact_lag.ExactLagModel`, so
    only cells with ``mu <= CW_EXACT_MU_MAX`` and a known geometry use it.
    """
    exact = np.zeros(cells.mu.shape, dtype=bool)
    if model != "inertial" and is_cw_probe(probe) and cells.n_lags >= 2:
        with np.errstate(invalid="ignore"):
            exact = (cells.mu <= CW_EXACT_MU_MAX) & np.isfinite(cells.phi + cells.dtheta)[:, None]
    return exact


def apply_exact_cells(
    probe: Any,
    cells: Cells,
    setup: FitSetup,
    res: CellEstimates,
    model: str,
    options: TableOptions,
    fit_noise: bool,
    noise_window: int,
) -> CellEstimates:
    """The estimates of :func:`cwproc.stages.epsilon.outer_scale.fit_cells` with the cw cells
    replaced by those of the exact model (:func:`fit_exact_cells`).

    The A-functions of the model's table at the fitted ``L_V`` (clipped to the table's
    range) still give method 1 (``e1``, Smalikho (2020), eq. 4 with ``A_1``) and the
    ratio; ``sf_model_exact`` is the exact model's structure function (NaN elsewhere).
    A pooled cw intercept of zero means no intercept was fitted: its ``noise`` is NaN.
    """
    exact = setup.exact
    fit = fit_exact_cells(
        probe, cells, setup.valid, exact, model, setup.c_model, fit_noise, noise_window
    )
    a1, a2 = res.a1.copy(), res.a2.copy()
    lags = np.arange(1, cells.n_lags + 1, dtype=float)
    lo, hi = options.outer_scale_range_m
    for rows, (_, table) in setup.tables.groups.values():  # A-functions at L_V: method 1, the ratio
        sel = exact & rows[:, None] & np.isfinite(fit["integral_scale"])
        ti, hi_ = np.nonzero(sel)
        g1, g2 = evaluate_table(
            table,
            lags[None, :],
            cells.height[hi_][:, None],
            cells.mu_eval[ti, hi_][:, None],
            np.clip(fit["integral_scale"][ti, hi_], lo, hi)[:, None],
        )
        a1[ti, hi_], a2[ti, hi_] = g1, g2 * setup.tables.sector[ti, hi_]
    e1, _, _ = fit_structure_function(cells.d, a1, setup.valid, setup.prior.predicted)
    fitted = np.where(exact, fit["noise_std"] > 0, res.fitted)
    noise = np.where(exact, fit["noise_std"], res.noise)
    return dataclasses.replace(
        res,
        a1=a1,
        a2=a2,
        e1=e1,
        efit=np.where(exact, fit["epsilon"], res.efit),
        noise=np.where(exact & ~fitted, np.nan, noise),
        fitted=fitted,
        sigma2=np.where(exact, fit["velocity_variance"], res.sigma2),
        l_v=np.where(exact, fit["integral_scale"], res.l_v),
        too_small=res.too_small | (exact & fit["below_range"]),
        sf_model_exact=fit["structure_function_model"],
    )
