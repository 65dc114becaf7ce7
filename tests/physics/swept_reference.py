"""Helpers of the tests of swept rays in strong wind: the model ``A_2`` as the ε stage forms it.

Not a test module: ``test_atable_swept_transport.py`` imports it (the tests folder on
``sys.path``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cwproc.physics import atable
from cwproc.physics.atable_interp import azimuth_bin_weights
from cwproc.physics.geometry import wind_components
from cwproc.physics.transfer import PulsedProbe
from cwproc.sim import exact_gaussian as eg
from cwproc.stages.epsilon.atable_fit import outer_scale_sector_factor


def tables(
    probe: PulsedProbe,
    phi_deg: float,
    rays: int,
    heights_m: tuple[float, float],
    mu_max: float,
    outer_scale_range_m: tuple[float, float] = (100.0, 250.0),
    **scan: Any,
) -> tuple:
    """The inertial and von Kármán tables of a ``rays``-ray scan, 4 lags.

    ``scan``: further :func:`cwproc.physics.atable.table_parameters` of the scan's rays
    (``swept=False, dwell=d`` for step-stare rays; continuous scans by default).
    """
    common = dict(
        phi_deg=phi_deg,
        delta_theta_deg=360.0 / rays,
        n_lags=4,
        height_range_m=heights_m,
        mu_max=mu_max,
        **scan,
    )
    inertial = atable.build_a_table(
        probe, atable.table_parameters(probe, model="inertial", **common)
    )
    finite = atable.build_a_table(
        probe,
        atable.table_parameters(
            probe, model="von_karman", outer_scale_range_m=outer_scale_range_m, **common
        ),
    )
    return inertial, finite


def exact_d(
    pattern: eg.ScanPattern,
    phi_deg: float,
    range_m: float,
    speed: float,
    outer_scale_m: float,
    gate_m: float,
    **options: Any,
) -> np.ndarray:
    """The generator's exact von Kármán ``D(0..4)`` per eps^(2/3) within one scan (0: the
    variance of V_r), the wind (``speed``, m s-1) towards 60 deg; ``options`` of
    :func:`cwproc.sim.exact_gaussian.block_covariance` (e.g. ``sweep_nodes``)."""
    u, v = wind_components(speed, 240.0)
    cov = eg.block_covariance(
        pattern,
        1,
        elevation_deg=phi_deg,
        range_m=range_m,
        epsilon=1.0,
        outer_scale_m=outer_scale_m,
        mean_wind=(u, v, 0.0),
        delta_r_m=gate_m,
        **options,
    )
    diag = np.diag(cov)
    d = [np.mean(diag[k:] + diag[:-k] - 2 * np.diag(cov, k)) for k in (1, 2, 3, 4)]
    return np.array([float(np.mean(diag)), *d])


def within_rotation_weights(rays: int, wind_to_deg: float) -> np.ndarray:
    """``(4, N_BINS)`` azimuth-node weights of the ``rays - l`` pairs of lag ``l`` of one scan.

    The first ray centred half a step clockwise from north (as
    :func:`cwproc.sim.exact_gaussian.conical_pattern` places it); the pairs do not wrap
    from the last ray to the first (:func:`cwproc.physics.block_stats.pair_azimuth_weights`).
    """
    step = 360.0 / rays
    out = []
    for lag in range(1, 5):
        middle = step * (np.arange(rays - lag) + 0.5 + 0.5 * lag)
        out.append(azimuth_bin_weights(np.radians(wind_to_deg - middle)))
    return np.array(out)


def estimator_a2(
    pair: tuple, height_m: float, mu: float, outer_scale_m: float, weights: np.ndarray
) -> np.ndarray:
    """``A_2(1..4)`` (m^(2/3)) over the pairs of ``weights``: the finite table's circle mean
    times the inertial sector ratio times the outer scale's own sector factor
    (:func:`outer_scale_sector_factor`, linear in ``log L_V`` between its nodes)."""
    inertial, finite = pair
    lags = np.arange(1, 5)
    h, m = np.full(4, height_m), np.full(4, mu)
    full = finite.evaluate(lags, h, m, outer_scale_m)[1]
    ratio = inertial.evaluate(lags, h, m, weights=weights)[1] / inertial.evaluate(lags, h, m)[1]
    factor = outer_scale_sector_factor(
        pair, lags.astype(float), np.array([height_m]), np.array([mu]), weights[None]
    )[0]
    log_nodes = np.log(finite.outer_scales_m)
    own = [np.interp(math.log(outer_scale_m), log_nodes, factor[:, j]) for j in range(4)]
    return full * ratio * np.asarray(own)
