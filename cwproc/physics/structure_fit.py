"""Least squares of the azimuth structure function, Smalikho (2020), eqs. 4-5.

``<D_L(l dtheta)> = eps^(2/3) A(l dy) + 2 sigma_e^2`` (Smalikho (2020), eq. 4) is linear
in ``eps^(2/3)`` and the noise term ``2 sigma_e^2``: :func:`fit_structure_function` is
its least squares over all valid lags, :func:`eq5_epsilon` its two-lag case (eq. 5).
Pure numpy; the lags are on the last axis of every array.
"""

from __future__ import annotations

import functools
import math

import numpy as np

#: fewest lags for a fitted noise intercept (one residual degree of freedom for its
#: standard error; on exact-statistics 24-ray step-stare scans the three-lag sigma_e came
#: out 5-8 times too large, while 144-ray scans with noise 0.3 m/s recover it; 4 would
#: trade the second for the first, see docs/physics-epsilon.md)
MIN_NOISE_LAGS = 3


#: the noise is fitted only where the predicted 2 sigma_e^2 is at least this share of
#: the smallest structure function of the block (below it, the prediction is used)
NOISE_DETECTABLE = 0.05


#: a fitted sigma_e further than this factor from the predicted one is not kept (flag 32)
NOISE_PLAUSIBLE = 2.0


def eq5_epsilon(d_l: np.ndarray, d_1: np.ndarray, a_l: np.ndarray, a_1: np.ndarray) -> np.ndarray:
    """Two-lag estimate of the dissipation rate (m2 s-3), Smalikho (2020), eq. 5.

    ``eps = [(D(l) - D(1)) / (A(l dy) - A(dy))]^(3/2)``; NaN where either difference is
    not positive.

    Parameters
    ----------
    d_l, d_1 : numpy.ndarray
        Structure function at lags l and 1 (m2 s-2).
    a_l, a_1 : numpy.ndarray
        A-function at lags l and 1 (m^(2/3)).
    """
    num = d_l - d_1
    den = a_l - a_1
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = num / den
    return np.where((num > 0) & (den > 0), ratio, np.nan) ** 1.5


def _lag_sum(x: np.ndarray) -> np.ndarray:
    """Sum over the last axis (the few lags), in order.

    numpy reduces such short rows sequentially too, so the sums are the same; an
    element-wise sum over the lags is several times faster than ``x.sum(-1)`` there.
    """
    return functools.reduce(np.add, np.moveaxis(x, -1, 0), np.zeros(x.shape[:-1]))


def fit_structure_function(
    d: np.ndarray,
    a: np.ndarray,
    valid: np.ndarray,
    noise_prior: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least squares of ``D = eps^(2/3) A + 2 sigma_e^2`` over the lags (last axis).

    Smalikho (2020), eq. 4. The intercept ``2 sigma_e^2`` is *determined* where at least
    :data:`MIN_NOISE_LAGS` lags are valid, it exceeds twice its standard error
    (``s sqrt(sum x^2 / (n sum x^2 - (sum x)^2))``, ``s^2`` the residual variance with
    ``n - 2`` degrees of freedom), and the predicted ``2 sigma_pred^2`` is at least
    :data:`NOISE_DETECTABLE` of the smallest ``D`` (a noise far below ``D`` at the first
    lag is not measurable: the intercept then measures the sampling error of ``D`` and
    the model's shape; on exact 24-ray VAD statistics it came out 6-8 times the true
    sigma_e, and eps 22 % low). Elsewhere (insignificant, negative, or too few lags)
    the slope is refitted with the intercept fixed at ``2 sigma_pred^2`` from
    ``noise_prior`` (the noise predicted from the SNR, :mod:`cwproc.physics.noise`), or
    at 0 without a prediction; ``sigma_e`` is then the prediction, or NaN -- never a
    measured 0.

    Parameters
    ----------
    d : numpy.ndarray
        Structure function (m2 s-2), lags on the last axis.
    a : numpy.ndarray
        A-function at the same lags (m^(2/3)).
    valid : numpy.ndarray of bool
        Lags to use.
    noise_prior : numpy.ndarray, optional
        Predicted sigma_e (m s-1), shape of ``d`` without the last axis.

    Returns
    -------
    (epsilon, noise_std, determined) : tuple of numpy.ndarray
        eps (m2 s-3), sigma_e (m s-1), and whether sigma_e is the fitted one; NaN where
        fewer than two lags are valid.
    """
    w = valid & np.isfinite(d) & np.isfinite(a)
    n = _lag_sum(w.astype(float))
    x = np.where(w, a, 0.0)
    y = np.where(w, d, 0.0)
    sx, sy = _lag_sum(x), _lag_sum(y)
    sxx, sxy = _lag_sum(x * x), _lag_sum(x * y)
    with np.errstate(invalid="ignore", divide="ignore"):
        det = n * sxx - sx**2
        slope = (n * sxy - sx * sy) / det
        intercept = (sy - slope * sx) / n
        resid = np.where(w, y - slope[..., None] * x - intercept[..., None], 0.0)
        s2 = _lag_sum(resid**2) / (n - 2)
        se_intercept = np.sqrt(s2 * sxx / det)
    prior = np.full(slope.shape, np.nan) if noise_prior is None else np.asarray(noise_prior)
    # an intercept above twice its standard error is kept; where there is a prediction,
    # so is one the fit measures precisely (standard error below half the predicted
    # 2 sigma_pred^2) within a factor NOISE_PLAUSIBLE of it: judged on the fitted value
    # alone, the blocks whose intercept fell low by chance took the prediction and those
    # that rose kept theirs, and the "fitted" noise read 14-37 % high (180-ray scans)
    with np.errstate(invalid="ignore", divide="ignore"):
        pred2 = 2.0 * np.nan_to_num(prior) ** 2
        plausible = np.abs(np.log(np.maximum(intercept, 1e-300) / pred2)) <= 2.0 * math.log(
            NOISE_PLAUSIBLE
        )
        precise = np.isfinite(prior) & (2.0 * se_intercept < pred2) & plausible
        significant = (intercept > 2.0 * se_intercept) | precise
    determined = (n >= MIN_NOISE_LAGS) & (intercept > 0) & significant
    # a noise term far below the smallest structure function cannot be told from the
    # sampling error of D and the model's shape: the fitted intercept then measures
    # those, not the noise (24-ray VADs: 6-8 times the true sigma_e)
    with np.errstate(invalid="ignore"):
        smallest = functools.reduce(
            np.minimum, np.moveaxis(np.where(w, d, np.inf), -1, 0), np.full(n.shape, np.inf)
        )
        detectable = ~np.isfinite(prior) | (2.0 * prior**2 >= NOISE_DETECTABLE * smallest)
    determined = determined & detectable
    fixed = np.where(np.isfinite(prior), 2.0 * np.nan_to_num(prior) ** 2, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        fixed_slope = (sxy - fixed * sx) / sxx
    slope = np.where(determined, slope, fixed_slope)
    intercept = np.where(determined, intercept, fixed)
    ok = (n >= 2) & (slope > 0) & np.isfinite(slope)
    eps = np.where(ok, np.where(ok, slope, 1.0) ** 1.5, np.nan)
    noise = np.where(determined, np.sqrt(np.maximum(intercept, 0.0) / 2.0), prior)
    return eps, np.where(ok, noise, np.nan), determined & ok
