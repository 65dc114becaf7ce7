"""Few-ray step-stare circles (12-ray VADs: two lags, 30 and 60 deg) in the fit (stage ``epsilon``).

The A-tables' azimuth nodes are too coarse for circles of steps of at least
:data:`~cwproc.physics.few_ray_sector.FEW_RAYS_STEP_DEG`: their ``A_2`` comes from the
direct two-beam sum over their pairs (:func:`cwproc.physics.few_ray_sector.sector_a2`),
inertial and at each outer-scale node, and the variance lost to the transport during
their dwell takes the outer scale's factor
(:func:`cwproc.physics.few_ray_sector.dwell_loss_ratio`). Used by
:func:`cwproc.stages.epsilon.outer_scale.fit_setup`.
"""

from __future__ import annotations

import numpy as np

from cwproc.physics.few_ray_sector import FEW_RAYS_STEP_DEG, dwell_loss_ratio, sector_a2
from cwproc.stages.epsilon.atable_fit import TableOptions
from cwproc.stages.epsilon.cells import Cells


def few_ray_inertial_a2(
    cells: Cells, options: TableOptions, a2: np.ndarray, sector: np.ndarray
) -> np.ndarray:
    """The inertial ``A_2`` ``(time, height, lag)`` with the few-ray circles'
    (:func:`few_ray_cells`) from :func:`cwproc.physics.few_ray_sector.sector_a2` (the
    inertial fit and the fallback of the finite-outer-scale one); the table's circle mean
    ``a2 / sector`` gives the probe's share."""
    few = few_ray_cells(cells, options) & np.all(np.isfinite(a2), axis=-1)
    if not few.any():
        return a2
    out = a2.copy()
    phi = float(np.nanmedian(cells.phi))
    dwell = float(options.dwell)
    for t, h in zip(*np.nonzero(few), strict=True):
        mu, rng = cells.mu_eval[t, h], cells.range_m[t, h]
        if not (np.isfinite(mu) and np.isfinite(rng)):
            continue
        out[t, h] = sector_a2(
            cells.lag_weights[t, h][None],
            float(cells.dtheta[t]),
            dwell,
            np.array([mu]),
            phi,
            np.array([rng]),
            np.array([1.0]),
            "inertial",
            (a2[t, h] / sector[t, h])[None],
        )[0, 0]
    return out


def carried_scale_factor(
    cells: Cells, options: TableOptions, scale_grid: np.ndarray, model: str
) -> np.ndarray:
    """``(time, height, nL)``: the outer scale's factor on the inertial variance lost to
    the transport during the dwell
    (:func:`cwproc.stages.epsilon.outer_scale.transport_loss`), for few-ray circles
    (:func:`few_ray_cells`: :func:`cwproc.physics.few_ray_sector.dwell_loss_ratio`); 1
    elsewhere (24- and 36-ray VADs keep the inertial loss)."""
    n_t, n_h = cells.range_m.shape
    out = np.ones((n_t, n_h, scale_grid.size))
    dwell = float(options.dwell)
    if dwell <= 0.0:
        return out
    phi = float(np.nanmedian(cells.phi))
    for t, h in zip(*np.nonzero(few_ray_cells(cells, options)), strict=True):
        mu, rng = cells.mu_eval[t, h], cells.range_m[t, h]
        if np.isfinite(mu) and np.isfinite(rng):
            out[t, h] = dwell_loss_ratio(
                float(cells.dtheta[t]), dwell, float(mu), phi, float(rng), scale_grid, model
            )
    return out


def few_ray_cells(cells: Cells, options: TableOptions) -> np.ndarray:
    """``(time, height)``: full circles of step-stare rays at least
    :data:`FEW_RAYS_STEP_DEG` apart (12-ray VADs: two lags, 30 and 60 deg)."""
    n_t, n_h = cells.range_m.shape
    dtheta = np.broadcast_to(np.asarray(cells.dtheta, float)[:, None], (n_t, n_h))
    coarse = np.isfinite(dtheta) & (dtheta >= FEW_RAYS_STEP_DEG - 1e-6)
    if options.swept or not coarse.any():
        return np.zeros((n_t, n_h), dtype=bool)  # (no partial-circle test of every cell)
    partial = cells.partial
    stare = not options.swept
    return stare & ~partial & np.isfinite(dtheta) & (dtheta >= FEW_RAYS_STEP_DEG - 1e-6)


def few_ray_circles(tables: tuple, partial: np.ndarray, dtheta: np.ndarray) -> np.ndarray:
    """Full circles of step-stare rays at least :data:`FEW_RAYS_STEP_DEG` apart."""
    params = tables[1].params
    stare = not params.get("swept", True)
    return stare & ~partial & np.isfinite(dtheta) & (dtheta >= FEW_RAYS_STEP_DEG - 1e-6)


def few_ray_factor(
    tables: tuple,
    lags: np.ndarray,
    height: np.ndarray,
    mu: np.ndarray,
    weights: np.ndarray,
    range_m: np.ndarray,
    circle: np.ndarray,
) -> np.ndarray:
    """``(cells, nL, n_lag)``: the factor on the finite table's circle mean ``circle``
    (``(cells, nL, n_lag)``, m^(2/3)) that gives few-ray circles the direct two-beam
    ``A_2`` of their pairs (:func:`cwproc.physics.few_ray_sector.sector_a2`), in place of
    :func:`cwproc.stages.epsilon.atable_fit.outer_scale_sector_factor`; over the inertial
    sector ratio, by which :func:`cwproc.stages.epsilon.outer_scale.fit_cells` multiplies."""
    inertial, finite = tables
    params = finite.params
    n_l = lags.size
    lag_b = np.broadcast_to(lags[None, :], (height.size, n_l))
    h_b = np.repeat(height[:, None], n_l, 1)
    mu_b = np.repeat(mu[:, None], n_l, 1)
    _, probe_circle = inertial.evaluate(lag_b, h_b, mu_b)
    direct = sector_a2(
        weights,
        float(params["delta_theta_deg"]),
        float(params.get("dwell", 0.0)),
        mu,
        float(params["phi_deg"]),
        range_m,
        finite.outer_scales_m,
        finite.model,
        probe_circle,
    )
    base = np.sum(inertial.node_ratio(lag_b, h_b, mu_b) * np.nan_to_num(weights), axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = direct / (circle * base[:, None, :])
    return np.where(np.isfinite(out) & (out > 0), out, 1.0)
