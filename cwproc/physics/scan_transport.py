"""The transport of the field between the scans of a block, as the measured wind tells it.

The removal of the block-mean VAD wind (:mod:`cwproc.physics.removed_share`) depends on
how far the wind carries the field from one scan to the next (Smalikho (2020), eq. 3).
The measured ``mu = U/V_s`` of a block holds the turbulent scatter of the block-mean
wind: :func:`transport_mu` takes its bias out, :func:`transport_weight` says how far
above that scatter the measured wind is, so that a field at rest, whose scans renew
(the no-transport limit of Smalikho (2020)), is not taken for one carried slowly.
Pure numpy.
"""

from __future__ import annotations

import math

import numpy as np


def transport_mu(
    mu: np.ndarray,
    share: np.ndarray,
    variance: np.ndarray,
    v_s: np.ndarray,
    n_scans: np.ndarray,
    phi_deg: float,
) -> np.ndarray:
    """``(cells, k)``: ``U/V_s`` of the field's transport, the measured ``mu`` less its bias.

    The block-mean VAD wind of turbulence at rest is not zero: the fit of one full circle
    takes the share ``S`` of sigma_V^2
    (:func:`cwproc.physics.removed_share.share_on_curve` at ``mu = 0``), nearly all of it
    in the horizontal wind, so each horizontal component of the mean of N
    independent scans scatters with ``S sigma_V^2 / (N cos^2 phi)`` and ``|U|^2`` is biased
    by twice that. ``mu_t = sqrt(max(mu^2 - 2 S var / (N cos^2 phi V_s^2), 0))``, ``var``
    the variance of V'_L standing for sigma_V^2. On exact 24-ray statistics of a field at
    rest (``R'/L_V`` 0.71) the measured ``mu`` was 0.006-0.038 (5-95 %), the bias
    ``sqrt(2 S var/N)/(V_s cos phi)`` 0.027 (exact: 0.025): without the correction the
    frozen transport between the scans made them nearly the same field, and eps 4-7 % high
    (36 and 24 rays).

    Parameters
    ----------
    mu : numpy.ndarray
        ``(cells,)`` measured ``U/V_s``.
    share : numpy.ndarray
        ``(cells, k)`` share ``S`` at the values of ``R'/L_V`` (``mu = 0``,
        :func:`cwproc.tables.removed_share.mean_removed_share`).
    variance, v_s, n_scans : numpy.ndarray
        ``(cells,)`` variance of V'_L (m2 s-2), ``V_s`` (m s-1), scans per block.
    phi_deg : float
        Elevation (degrees).
    """
    cos2 = math.cos(math.radians(phi_deg)) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        bias = 2.0 * share * (variance / (n_scans * cos2 * v_s**2))[:, None]
    mu_t = np.sqrt(np.maximum(np.asarray(mu, float)[:, None] ** 2 - np.nan_to_num(bias), 0.0))
    return np.nan_to_num(mu_t, nan=0.0)


def transport_weight(
    mu: np.ndarray,
    share: np.ndarray,
    variance: np.ndarray,
    v_s: np.ndarray,
    n_scans: np.ndarray,
    phi_deg: float,
) -> np.ndarray:
    """``(cells, k)`` in [0, 1]: how far the measured transport stands above its scatter.

    ``rest = sqrt(S var / (N cos^2 phi V_s^2))`` is the rms of each horizontal component
    of the block-mean wind of a field at rest over ``V_s`` (:func:`transport_mu`); the
    weight ramps from 0 at ``mu = 2 rest`` to 1 at ``4 rest``. A field at rest exceeds
    ``2 rest`` in ``exp(-2)`` = 14 % of its blocks (``|U|/rest`` is Rayleigh), ``4 rest``
    in 0.03 %. Arguments as :func:`transport_mu`.
    """
    cos2 = math.cos(math.radians(phi_deg)) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        rest = np.sqrt(share * (variance / (n_scans * cos2 * v_s**2))[:, None])
        ramp = (np.asarray(mu, float)[:, None] / rest - 2.0) / 2.0
    return np.clip(np.nan_to_num(ramp, nan=0.0), 0.0, 1.0)
