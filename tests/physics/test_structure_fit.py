"""The least squares of Smalikho (2020), eq. 4: the intercept's error and when the noise is fitted.

Exact truth: block-mean structure functions drawn as Gaussian vectors with a known
covariance across the lags (neighbouring lags share rays, so their errors correlate),
around ``eps^(2/3) A + 2 sigma_e^2``.
"""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics.structure_fit import (
    NOISE_PRECISION,
    fit_structure_function,
    intercept_standard_error,
)

A = np.array([1.0, 2.6, 4.3, 6.0])  # A_2 at lags 1-4 (m^(2/3)), inertial-like growth
EPS = 0.01  # m2 s-3
SCANS = 10  # scans per block: the covariance is estimated from their scatter


def lag_covariance(scale: float, rho: float = 0.9) -> np.ndarray:
    """Covariance of the block-mean D over the lags (m4 s-4): strongly correlated lags."""
    lags = np.arange(A.size)
    sd = scale * np.sqrt(1.0 + lags)
    return sd[:, None] * sd[None, :] * rho ** np.abs(lags[:, None] - lags[None, :])


def blocks(sigma_e: float, cov: np.ndarray, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` blocks: block-mean D and the covariance estimated from their 10 scans."""
    rng = np.random.default_rng(seed)
    mean = EPS ** (2 / 3) * A + 2 * sigma_e**2
    per_scan = mean + rng.multivariate_normal(np.zeros(A.size), SCANS * cov, (n, SCANS))
    d = per_scan.mean(axis=1)
    dev = per_scan - d[:, None, :]
    d_cov = np.einsum("bsi,bsj->bij", dev, dev) / (SCANS - 1) / SCANS
    return d, d_cov


def test_intercept_error_is_the_scatter_of_the_intercept():
    """``sqrt(c^T C c)`` is the standard deviation of the intercept over draws (to 2 %)."""
    cov = lag_covariance(2e-3)
    rng = np.random.default_rng(1)
    d = EPS ** (2 / 3) * A + rng.multivariate_normal(np.zeros(A.size), cov, 40000)
    design = np.stack([A, np.ones_like(A)], axis=1)
    intercept = np.linalg.lstsq(design, d.T, rcond=None)[0][1]
    se = intercept_standard_error(A, np.ones(A.size, bool), cov)
    assert intercept.std(ddof=1) == pytest.approx(float(se), rel=0.02)  # sd known to 0.4 %
    # the residual form treats the lags as independent: far below the scatter here
    resid = d.T - design @ np.linalg.lstsq(design, d.T, rcond=None)[0]
    s2 = (resid**2).sum(axis=0) / (A.size - 2)
    residual_se = np.sqrt(s2 * (A**2).sum() / (A.size * (A**2).sum() - A.sum() ** 2))
    assert np.mean(residual_se) < 0.6 * intercept.std(ddof=1)


@pytest.mark.parametrize("precision", [0.3, 0.45])
def test_fitted_noise_is_unbiased_where_it_is_kept(precision):
    """Kept on its precision, the mean fitted sigma_e is the truth (within 3 s.e. + 2 %).

    ``precision`` sets the intercept's standard error as a share of ``2 sigma_e^2``,
    below :data:`NOISE_PRECISION`: most blocks keep their fit, the others (whose scans
    scattered more) take the prediction. A rule on the fitted value (above twice its
    error) would keep the blocks that rose by chance. Only the floor (sigma_e at least
    half the prediction) cuts by value, 1.5 errors or more below: at 0.45 the kept
    sigma_e^2 reads +5 %, its root, the product's sigma_e, +0.5 % (the root of an
    unbiased intercept reads low by about ``(SE / 2 sigma_e^2)^2 / 8``).
    """
    assert precision < NOISE_PRECISION
    sigma_e = 0.1
    pred2 = 2 * sigma_e**2
    unit = float(intercept_standard_error(A, np.ones(A.size, bool), lag_covariance(1.0)))
    d, d_cov = blocks(sigma_e, lag_covariance(precision * pred2 / unit), 6000, seed=7)
    prior = np.full(d.shape[0], sigma_e)
    eps, noise, fitted = fit_structure_function(
        d, np.broadcast_to(A, d.shape), np.ones(d.shape, bool), prior, d_cov
    )
    assert 0.5 < fitted.mean() < 0.999
    ratio = noise[fitted] / sigma_e
    assert abs(ratio.mean() - 1) < 3 * ratio.std(ddof=1) / np.sqrt(ratio.size) + 0.02
    assert np.mean(noise / sigma_e) == pytest.approx(1.0, abs=0.02)  # the product's
    # eps over all blocks, fitted noise or predicted, is unbiased too
    e = eps / EPS
    assert abs(e.mean() - 1) < 3 * e.std(ddof=1) / np.sqrt(e.size) + 0.01


def test_a_wrong_prediction_does_not_overrule_a_measured_noise():
    """Noise 0.3 m/s, an SNR that predicts 0.1: the fit, three errors away, is kept."""
    sigma_e = 0.3
    d, d_cov = blocks(sigma_e, lag_covariance(4e-3), 400, seed=3)
    prior = np.full(d.shape[0], 0.1)
    eps, noise, fitted = fit_structure_function(
        d, np.broadcast_to(A, d.shape), np.ones(d.shape, bool), prior, d_cov
    )
    assert fitted.mean() > 0.95
    assert np.median(noise[fitted]) == pytest.approx(sigma_e, rel=0.05)
    assert np.median(eps) == pytest.approx(EPS, rel=0.1)
    assert np.median(noise[fitted]) == pytest.approx(sigma_e, rel=0.3)


def test_an_imprecise_fit_is_rarely_kept():
    """An intercept error equal to ``2 sigma_e^2``: kept only where the scans scattered little."""
    sigma_e = 0.1
    unit = float(intercept_standard_error(A, np.ones(A.size, bool), lag_covariance(1.0)))
    d, d_cov = blocks(sigma_e, lag_covariance(2 * sigma_e**2 / unit), 4000, seed=9)
    prior = np.full(d.shape[0], sigma_e)
    _, noise, fitted = fit_structure_function(
        d, np.broadcast_to(A, d.shape), np.ones(d.shape, bool), prior, d_cov
    )
    assert fitted.mean() < 0.1
    assert np.all(noise[~fitted] == sigma_e)


def test_a_noise_the_data_cannot_measure_is_the_prediction_flagged():
    """An intercept error of three times 2 sigma_e^2: the prediction, never a fitted value."""
    sigma_e = 0.05
    pred2 = 2 * sigma_e**2
    unit = float(intercept_standard_error(A, np.ones(A.size, bool), lag_covariance(1.0)))
    d, d_cov = blocks(sigma_e, lag_covariance(3 * pred2 / unit), 2000, seed=5)
    prior = np.full(d.shape[0], sigma_e)
    _, noise, fitted = fit_structure_function(
        d, np.broadcast_to(A, d.shape), np.ones(d.shape, bool), prior, d_cov
    )
    assert fitted.mean() < 0.05  # only fits that contradict the prediction by 3 s.e.
    assert np.all(noise[~fitted & np.isfinite(noise)] == sigma_e)


def test_a_prediction_that_leaves_no_turbulence_gives_way_to_the_fit():
    """Noise 0.05 m/s, an SNR that predicts 0.45: fixed there, eps^(2/3) would be < 0."""
    sigma_e = 0.05
    d, d_cov = blocks(sigma_e, lag_covariance(1e-3), 400, seed=11)
    prior = np.full(d.shape[0], 0.45)  # 2 sigma_pred^2 = 0.405: above D(1), D(2), D(3)
    eps, noise, fitted = fit_structure_function(
        d, np.broadcast_to(A, d.shape), np.ones(d.shape, bool), prior, d_cov
    )
    assert np.all((d - 2 * 0.45**2) @ A < 0)  # the slope with that intercept
    assert fitted[np.isfinite(eps)].all() and np.isfinite(eps).mean() > 0.95
    assert np.median(eps) == pytest.approx(EPS, rel=0.1)
    assert np.median(noise[fitted]) == pytest.approx(sigma_e, rel=0.3)
