"""The correlated-circle factors of the error bars, kept in the table store.

:func:`circle_variance_factor` interpolates
:func:`cwproc.physics.scan_correlation.refit_jackknife_factor` (the variance of a block's
variance statistic over the expectation of its refit jackknife, correlated scans over
independent ones) from slices on ``FACTOR_X`` x ``FACTOR_ANGLES`` per node of
``FACTOR_MU`` (:func:`cwproc.physics.scan_correlation.circle_factor_slice`), computed
when a cell first needs that ``mu`` and kept in memory and on disk
(:func:`cwproc.tables.store.cached_arrays`, keyed by the parameters and the hash of the
code of :mod:`cwproc.physics.scan_correlation`).
"""

from __future__ import annotations

import functools

import numpy as np

from cwproc import progress
from cwproc.physics.scan_correlation import (
    FACTOR_ANGLES,
    FACTOR_MU,
    FACTOR_X,
    circle_factor_slice,
)
from cwproc.tables.store import cached_arrays, code_digest

#: the module whose code the factors depend on (:func:`cwproc.tables.store.code_digest`)
CODE_ROOT = "cwproc.physics.scan_correlation"


@functools.lru_cache(maxsize=512)
def stored_factor_slice(
    n_rays: int, n_scans: int, interval: float, phi_deg: float, model: str, mu_node: int
) -> np.ndarray:
    """``(x, angle)``: :func:`cwproc.physics.scan_correlation.circle_factor_slice` at the
    ``mu_node``-th node of ``FACTOR_MU`` (about 0.07 s for 24 rays and 10 scans, 0.2 s
    for 36, once; then read from disk). Read-only: shared by every caller through the cache."""
    mu = float(FACTOR_MU[mu_node])
    shape = (FACTOR_X.size, FACTOR_ANGLES.size)
    if mu <= 0.0 or n_scans < 2:
        return np.ones(shape)

    def compute() -> dict[str, np.ndarray]:
        return {"factor": circle_factor_slice(n_rays, n_scans, interval, phi_deg, model, mu)}

    def valid(arrays: dict[str, np.ndarray]) -> bool:
        factor = arrays.get("factor")
        return factor is not None and factor.shape == shape and bool(np.isfinite(factor).all())

    params = {"rays": n_rays, "scans": n_scans, "interval": interval, "phi_deg": phi_deg}
    params |= {"model": model, "mu": mu, "code": code_digest(CODE_ROOT)}
    params |= {"x": FACTOR_X.tolist(), "angles": FACTOR_ANGLES.tolist()}
    out = cached_arrays("scan-factor", params, compute, valid)["factor"]
    out.flags.writeable = False
    return out


def circle_variance_factor(
    n_rays: np.ndarray,
    n_scans: np.ndarray,
    interval: np.ndarray,
    mu: np.ndarray,
    ratio: np.ndarray,
    angle_deg: np.ndarray,
    phi_deg: float,
    model: str,
) -> np.ndarray:
    """``(cells,)`` the refit jackknife's correlated-circle factor, from tabulated nodes.

    :func:`cwproc.physics.scan_correlation.refit_jackknife_factor` of full circles.

    Per configuration ``(M rays, N scans, T_int/T_scan)`` and node of ``FACTOR_MU``
    a table on ``FACTOR_X`` x ``FACTOR_ANGLES`` (:func:`stored_factor_slice`,
    no noise: the noise only dilutes the correlation), interpolated linearly in ``mu``,
    ``log(R'/L_V)`` and the start angle; cells without an angle (NaN) take the mean
    over the angles. 1 where a value is not finite or ``mu`` is 0.

    Parameters
    ----------
    n_rays, n_scans, interval : numpy.ndarray
        ``(cells,)`` rays per circle, scans per block, ``T_int/T_scan``.
    mu, ratio : numpy.ndarray
        ``(cells,)`` ``U/V_s`` of the transport and ``R'/L_V``.
    angle_deg : numpy.ndarray
        ``(cells,)`` angle of the block's first ray from the wind's direction of motion,
        in the scan's sense of rotation (deg).
    phi_deg : float
        Elevation (deg).
    model : str
        Correlation model.
    """
    mu = np.asarray(mu, float)
    ratio = np.asarray(ratio, float)
    out = np.ones(mu.shape)
    ok = np.isfinite(mu) & (mu > 0) & np.isfinite(ratio) & (ratio > 0)
    ok &= np.isfinite(n_rays) & (n_rays >= 3) & np.isfinite(n_scans) & (n_scans >= 2)
    if not ok.any():
        return out
    m = np.clip(mu, 0.0, FACTOR_MU[-1])
    j = np.clip(np.searchsorted(FACTOR_MU, m, side="right") - 1, 0, FACTOR_MU.size - 2)
    w_mu = (m - FACTOR_MU[j]) / (FACTOR_MU[j + 1] - FACTOR_MU[j])
    lx = np.log(FACTOR_X)
    pos = (np.log(np.clip(ratio, FACTOR_X[0], FACTOR_X[-1])) - lx[0]) / (lx[1] - lx[0])
    i0 = np.clip(np.floor(np.nan_to_num(pos)).astype(int), 0, lx.size - 2)
    w_x = np.nan_to_num(pos) - i0
    step = FACTOR_ANGLES[1] - FACTOR_ANGLES[0]
    a_pos = np.mod(np.nan_to_num(angle_deg), 360.0) / step
    a0 = np.floor(a_pos).astype(int) % FACTOR_ANGLES.size
    w_a = a_pos - np.floor(a_pos)
    no_angle = ~np.isfinite(angle_deg)
    keys = np.stack([n_rays, n_scans, np.round(interval, 2), j], -1)
    uniq, inverse = np.unique(np.where(ok[:, None], keys, -1.0), axis=0, return_inverse=True)
    # a new geometry's first day computes its nodes (0.07-0.2 s each): a bar on a terminal
    nodes = progress.track(list(enumerate(uniq)), desc="scan factors (new geometry)")
    for u, key in nodes:
        at = np.nonzero((inverse.ravel() == u) & ok)[0]
        if at.size == 0:
            continue
        rays, scans, inter, node = int(key[0]), int(key[1]), float(key[2]), int(key[3])
        lo, hi = (
            stored_factor_slice(rays, scans, inter, round(phi_deg, 2), model, k)
            for k in (node, node + 1)
        )
        grid = (1.0 - w_mu[at, None, None]) * lo + w_mu[at, None, None] * hi  # (c, x, a)
        c = np.arange(at.size)
        in_x = (1.0 - w_x[at, None]) * grid[c, i0[at]] + w_x[at, None] * grid[c, i0[at] + 1]
        a1 = (a0[at] + 1) % FACTOR_ANGLES.size
        value = (1.0 - w_a[at]) * in_x[c, a0[at]] + w_a[at] * in_x[c, a1]
        out[at] = np.where(no_angle[at], in_x.mean(axis=1), value)
    return out
