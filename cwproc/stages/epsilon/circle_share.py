"""The variance share the block-mean VAD wind takes from full circles of correlated scans.

The finite-outer-scale fit (:func:`cwproc.stages.epsilon.outer_scale.finite_scale_inputs`)
subtracts from the probe-passed variance the share of sigma_V^2 that the block-mean VAD
wind removes. Scans that a light wind carries less than ``L_V`` from one another are
nearly the same field, and the block mean then takes up to N times the share of
independent scans (:func:`cwproc.physics.removed_share.circle_removed_variance`); the
transport counts as far as the measured wind stands above its turbulent scatter
(:func:`cwproc.physics.scan_transport.transport_weight`).
"""

from __future__ import annotations

import numpy as np

from cwproc.physics.removed_share import circle_removed_variance
from cwproc.physics.scan_transport import transport_mu, transport_weight
from cwproc.stages.epsilon.cells import Cells
from cwproc.tables.removed_share import mean_removed_share

#: every this many nodes of the L_V grid of the fit (ratio 1.1) the correlated circles'
#: variance share is evaluated (ratio 1.77, the spacing of the removal grid's ``R'/L_V``
#: nodes), and interpolated in ``log L_V`` between
SHARE_NODE_STEP = 6


def correlated_circle_share(
    independent: np.ndarray,
    cells: Cells,
    ct: np.ndarray,
    ch: np.ndarray,
    scale_grid: np.ndarray,
    n_scans: np.ndarray,
    phi: float,
    model: str,
) -> np.ndarray:
    """``(cells, grid)``: the variance share of full circles of correlated scans.

    :func:`cwproc.physics.removed_share.circle_removed_variance` at the transport
    :func:`cwproc.physics.scan_transport.transport_mu`, taken in by
    :func:`cwproc.physics.scan_transport.transport_weight` over ``independent`` (the
    share of independent scans), on every :data:`SHARE_NODE_STEP`-th node of
    ``scale_grid`` and interpolated (log-log) to the others.
    """
    sub = np.unique(np.r_[np.arange(0, scale_grid.size, SHARE_NODE_STEP), scale_grid.size - 1])
    ratio = cells.radius[ct, ch, None] / scale_grid[None, sub]
    setting = (cells.mu_eval[ct, ch], *rest_inputs(ratio, cells, ct, ch, phi, model))
    weight = transport_weight(*setting, n_scans, phi)
    carried = np.full(weight.shape, np.nan)
    moving = np.nonzero((weight > 0.0).any(axis=-1))[0]  # the others keep the share
    if moving.size:
        carried[moving] = circle_removed_variance(
            np.radians(cells.dtheta[ct[moving]]),
            cells.d.shape[2],
            ratio[moving],
            transport_mu(*(a[moving] for a in setting), n_scans[moving], phi),
            cells.interval[ct[moving]],
            n_scans[moving],
            phi,
            model,
        )
    pos = np.interp(np.log(scale_grid), np.log(scale_grid[sub]), np.arange(sub.size))
    i0 = np.minimum(pos.astype(int), sub.size - 2)
    frac = pos - i0
    with np.errstate(divide="ignore", invalid="ignore"):
        log_c = np.log(carried)
        carried = np.exp((1.0 - frac) * log_c[:, i0] + frac * log_c[:, i0 + 1])
    weight = (1.0 - frac) * weight[:, i0] + frac * weight[:, i0 + 1]
    mixed = (1.0 - weight) * independent + weight * carried
    return np.where(np.isfinite(carried), mixed, independent)


def rest_inputs(
    ratio: np.ndarray, cells: Cells, ct: np.ndarray, ch: np.ndarray, phi: float, model: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(S, var, V_s)`` of the cells ``(ct, ch)`` for
    :func:`cwproc.physics.scan_transport.transport_mu`: the share of independent scans at
    rest at ``ratio`` (``(cells, k)`` of ``R'/L_V``), the variance of V'_L and the scan
    speed."""
    rest = mean_removed_share(ratio, phi, model, 0.0)
    return rest, cells.var_raw[ct, ch], cells.v_s[ct, ch]
