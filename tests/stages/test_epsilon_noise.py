"""The predicted noise as a prior decided by the data, its calibration, the tail guard
(issue 29, items 2 and 4)."""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics.noise import CALIBRATION_MIN_CELLS, noise_calibration
from cwproc.physics.structure_fit import (
    MIN_POOLED_CELLS,
    fit_structure_function,
    free_intercept,
    gls_intercept,
    inverse_weight,
    pooled_covariance,
    weighted_intercept,
)
from cwproc.stages.epsilon.flags import unresolved_scale


def _cells(n: int, k: float, rel_err: float, seed: int = 3):
    """Intercepts of ``n`` cells whose noise is ``k`` times the predicted one."""
    rng = np.random.default_rng(seed)
    pred = rng.uniform(0.05, 0.15, n)
    truth = 2.0 * (k * pred) ** 2
    se = rel_err * truth
    return truth + se * rng.standard_normal(n), se, pred


@pytest.mark.parametrize("k", [0.5, 1.0, 1.5])
def test_calibration_recovers_the_factor_the_snr_misstates(k):
    b, se, pred = _cells(400, k, 0.3)
    got, got_se, n = noise_calibration(b, se, pred)
    assert n > 300
    # 400 cells of 30 % error in sigma_e^2: k to about 1 %; within 3 of its errors
    assert abs(got - k) < 3 * got_se
    assert 0.002 < got_se / k < 0.03


def test_calibration_resists_a_few_wild_intercepts_and_needs_enough_cells():
    b, se, pred = _cells(200, 1.0, 0.3)
    b[:20] *= 8.0  # the model's shape at the first lags, not the noise
    got, _, _ = noise_calibration(b, se, pred)
    assert abs(got - 1.0) < 0.06  # a weighted mean would read about 1.3
    few = noise_calibration(b[: CALIBRATION_MIN_CELLS - 1], se[:9], pred[:9])
    assert np.isnan(few[0])


def test_a_calibration_of_few_blocks_is_reported_not_applied():
    """k far from 1 and precise, some cells on the prediction: applied with 10 blocks,
    not with 2 (the cells of a block share its turbulence across heights)."""
    import xarray as xr

    from cwproc.stages.epsilon.noise_prior import CALIBRATION_MIN_BLOCKS, calibration_applies

    def product(blocks: int) -> xr.Dataset:
        flag = np.full((blocks, 3), 32, dtype=np.int32)  # noise predicted from the SNR
        return xr.Dataset({"turbulence_flag": (("time", "height"), flag)})

    calibration = (0.5, 0.05, 400)
    assert calibration_applies(calibration, [product(CALIBRATION_MIN_BLOCKS)])
    assert calibration_applies(calibration, [product(4), product(CALIBRATION_MIN_BLOCKS - 4)])
    assert not calibration_applies(calibration, [product(2)])
    assert not calibration_applies((1.02, 0.05, 400), [product(CALIBRATION_MIN_BLOCKS)])
    # far from 1 by five of its errors, but imprecise (24-ray step-stare, mu 1, truth 1)
    assert not calibration_applies((3.6, 0.7, 200), [product(200)])


def test_the_model_error_of_the_intercept_keeps_a_small_noise_uncalibrated():
    """sigma_e 0.05 (2 sigma_e^2 = 0.005) under D(1) = 0.25: a model shape 1.3 % of D(1)
    off at the first lags moves every intercept by 0.0033 (k^2 1.65, k 1.29), a shift
    shared by all cells that no number of cells averages away. The model error
    (2 % of D(1)) makes k = 1.29 insignificant; the same day with sigma_e 0.1 (the
    prediction x1.5 too high, k 0.67) is still calibrated."""
    import xarray as xr

    from cwproc.stages.epsilon.noise_prior import calibration_applies, day_calibration

    rng = np.random.default_rng(3)
    flag = np.full((100, 3), 32, dtype=np.int32)
    products = [xr.Dataset({"turbulence_flag": (("time", "height"), flag)})]
    first = np.full(300, 0.25)

    def day(sigma_e: float, predicted: float) -> tuple:
        b = 2 * sigma_e**2 + 0.013 * 0.25 + rng.normal(0.0, 0.1 * 2 * sigma_e**2, 300)
        se = np.full(300, 0.1 * 2 * sigma_e**2)
        return day_calibration([(b, se, np.full(300, predicted), first)])

    small = day(0.05, 0.05)
    assert small[0] > 1.2 and small[1] < 0.02  # statistically "significant"
    assert small[4] > 0.3  # the model error of k
    assert not calibration_applies(small, products)
    large = day(0.1, 0.15)
    assert abs(large[0] - 0.72) < 0.03 and large[4] < 0.1
    assert calibration_applies(large, products)


def test_the_data_overrule_a_prediction_that_is_too_high():
    """D = eps^(2/3) A + 2 sigma_e^2 with sigma_e 0.1, the prediction 0.2 (x2 too high),
    the intercept measured to 5 %: the test with both errors keeps the data."""
    a = np.array([1.0, 1.6, 2.1, 2.5])
    d = 0.05 * a + 2 * 0.1**2
    cov = np.diag(np.full(4, 1e-7))
    b, se, n = free_intercept(d, a, np.ones(4, bool), cov)
    assert b == pytest.approx(0.02) and n == 4 and se < 0.05 * b
    eps, noise, fitted = fit_structure_function(d, a, np.ones(4, bool), np.array(0.2), cov)
    assert fitted and noise == pytest.approx(0.1)
    assert eps == pytest.approx(0.05**1.5)
    # a prediction within its own error of the data and an imprecise intercept: the
    # prediction is kept
    cov_bad = np.diag(np.full(4, 4e-3))
    _, noise, fitted = fit_structure_function(d, a, np.ones(4, bool), np.array(0.12), cov_bad)
    assert not fitted and noise == pytest.approx(0.12)


def test_integral_scale_below_the_transverse_sampling_is_flagged():
    l_v = np.array([20.0, 80.0, np.nan, 200.0])
    dy = np.array([37.0, 37.0, 37.0, np.nan])
    assert unresolved_scale(l_v, dy).tolist() == [True, False, False, False]


def _retrieved_over_truth(ratio: float, seed: int, continuous: bool = True):
    """The streamline chain on exact statistics (mu 0, eps 0.01 m2 s-3, L_V 150 m,
    sigma_e 0.1 m s-1, 35.3 deg, 100 blocks of 10 scans of 72 rays in 36 s, continuous or
    step-stare) whose SNR predicts ``ratio x sigma_e``: the turbulence product and the
    finite eps and sigma_e over their truth."""
    import dataclasses

    from cwproc.config import load_config
    from cwproc.pipeline import process_scans
    from cwproc.sim import exact_gaussian as eg

    phi, height = 35.3, 100.0
    scans = eg.gaussian_scans(
        pattern=eg.conical_pattern(72, 36.0, continuous=continuous),
        n_scans=10,
        n_blocks=100,
        elevation_deg=phi,
        ranges_m=[height / np.sin(np.deg2rad(phi))],
        epsilon=0.01,
        outer_scale_m=150.0,
        wind_speed_m_s=0.0,
        wind_direction_deg=250.0,
        noise_std_m_s=0.1 * ratio,
        noise_factor=1.0 / ratio,
        seed=seed,
    )
    base = load_config("streamline")
    config = dataclasses.replace(base, turbulence=dataclasses.replace(base.turbulence, n_scans=10))
    with np.errstate(all="ignore"):
        turb = process_scans(scans, config, [])["turbulence"]
    eps = turb["epsilon"].values[:, 0] / 0.01
    sig = turb["noise_std"].values[:, 0] / 0.1
    return turb, eps[np.isfinite(eps)], sig[np.isfinite(sig)]


@pytest.mark.slow
@pytest.mark.parametrize("ratio", [0.5, 1.5])
def test_eps_and_noise_hold_when_the_snr_misstates_the_noise(ratio):
    """Exact statistics (72-ray step-stare scans, mu 0, eps 0.01 m2 s-3, L_V 150 m,
    sigma_e 0.1 m s-1, 35.3 deg, 100 blocks of 10 scans) whose SNR predicts ``ratio x
    sigma_e``: mean eps within 5 % and mean sigma_e within 10 % of the truth, the
    calibration within 10 % (before: eps +6 % with the prediction x0.5 kept)."""
    turb, eps, sig = _retrieved_over_truth(ratio, seed=29, continuous=False)
    assert eps.size >= 95
    assert abs(eps.mean() - 1.0) < 0.05, eps.mean()
    assert abs(sig.mean() - 1.0) < 0.10, sig.mean()
    assert float(turb["noise_std_calibration"]) == pytest.approx(1.0 / ratio, rel=0.1)


def _lag_covariance(d: np.ndarray, rel: float = 0.05, corr: float = 0.8) -> np.ndarray:
    """Covariance of D over 4 lags: ``rel`` relative errors, neighbours correlated ``corr``."""
    lags = np.arange(d.shape[-1])
    shape = corr ** np.abs(np.subtract.outer(lags, lags))
    return (rel * d)[..., :, None] * (rel * d)[..., None, :] * shape


def test_generalised_least_squares_is_exact_and_at_least_as_precise():
    """On D = eps^(2/3) A + 2 sigma_e^2 exactly, the GLS intercept is 2 sigma_e^2; with the
    true covariance of D as weight its standard error is at most the equal weights' (the
    Gauss-Markov theorem), here 0.83 of it with lags correlated 0.8."""
    a = np.array([1.0, 1.6, 2.1, 2.5])
    d = 0.05 * a + 2 * 0.1**2
    cov = _lag_covariance(d)
    b, se = weighted_intercept(d, a, cov, cov)
    assert b == pytest.approx(0.02, rel=1e-12)
    _, se_ols, _ = free_intercept(d, a, np.ones(4, bool), cov)
    assert se < 0.9 * se_ols
    # the inverse is that of the weight; a singular or missing weight gives NaN
    np.testing.assert_allclose(inverse_weight(cov) @ cov, np.eye(4), atol=1e-9)
    b_nan, se_nan = gls_intercept(d, a, np.full((4, 4), np.nan), cov)
    assert np.isnan(b_nan) and np.isnan(se_nan)


def test_pooled_covariance_is_the_shape_the_blocks_share():
    """The relative covariance averaged over a height's blocks, at their mean D; NaN with
    fewer than MIN_POOLED_CELLS blocks."""
    rng = np.random.default_rng(1)
    a = np.array([1.0, 1.6, 2.1, 2.5])
    d = (0.05 * a + 0.02) * rng.uniform(0.5, 2.0, (MIN_POOLED_CELLS, 1, 1))
    cov = _lag_covariance(d)
    usable = np.ones(d.shape[:2], bool)
    shared = pooled_covariance(d, cov, usable)[0]
    mean_d = d[:, 0].mean(0)
    np.testing.assert_allclose(shared, _lag_covariance(mean_d), rtol=1e-12)
    usable[0] = False
    assert np.isnan(pooled_covariance(d, cov, usable)).all()


def test_one_factor_must_explain_the_cells_to_be_applied():
    """A calibration whose cells scatter about k^2 by far more than their errors (the
    prediction off by a factor that varies from cell to cell) is not applied."""
    import xarray as xr

    from cwproc.stages.epsilon.noise_prior import (
        CALIBRATION_MAX_DISPERSION,
        calibration_applies,
        day_calibration,
    )

    product = xr.Dataset({"turbulence_flag": (("time", "height"), np.full((20, 3), 32))})
    b, se, pred = _cells(400, 0.7, 0.3)
    one = day_calibration([(b, se, pred)])
    assert abs(one[3] - 1.0) < 0.2  # errors that explain the scatter: about 1
    assert calibration_applies(one, [product])
    rng = np.random.default_rng(4)
    varied = pred * rng.uniform(0.3, 3.0, pred.size)  # a factor per cell
    many = day_calibration([(b, se, varied)])
    assert many[3] > CALIBRATION_MAX_DISPERSION
    assert not calibration_applies(many, [product])


@pytest.mark.slow
@pytest.mark.parametrize("ratio", [0.5, 1.5])
def test_noise_and_eps_of_swept_scans_when_the_snr_misstates_the_noise(ratio):
    """Exact statistics of 72-ray continuous scans at mu 0 (36 s, eps 0.01 m2 s-3, L_V
    150 m, sigma_e 0.1 m s-1, 35.3 deg, 100 blocks of 10 scans) whose SNR predicts
    ``ratio x sigma_e``. Before (``benchmarks/bench_epsilon_noise.py``, seed 16): sigma_e
    1.115 and eps 0.957 of the truth with the prediction x1.5 (the median of the
    equal-weight intercepts, k 0.730 for 0.667). The calibration within three of its
    standard errors of ``1/ratio``, mean sigma_e within 10 % and mean eps within 5 % and
    three standard errors of the truth. (At mu 1 the intercepts still read ``2
    sigma_e^2`` about 8 % high on average, the A-function's shape at the first lags of a
    swept ray carried by the wind: sigma_e 1.027, 1.057 and 1.10 on three seeds.)"""
    turb, eps, sig = _retrieved_over_truth(ratio, seed=2912)
    assert eps.size >= 95
    eps_se = eps.std(ddof=1) / np.sqrt(eps.size)
    assert abs(eps.mean() - 1.0) < min(0.05, 3 * eps_se), (eps.mean(), eps_se)
    assert abs(sig.mean() - 1.0) < 0.10, sig.mean()
    k = turb["noise_std_calibration"]
    assert abs(float(k) - 1.0 / ratio) < 3 * k.attrs["standard_error"], (float(k), k.attrs)
