"""eps of step-stare VADs from the exact expected D(l) of the block-mean residuals.

The expected structure function and variance of ``V'_L`` (the residuals of the
block-mean VAD fit, Smalikho (2020), eqs. 1-2) of a block of 24- or 36-ray step-stare
scans, from the exact covariance of the probe-averaged velocities
(:func:`cwproc.sim.exact_gaussian.block_covariance`), go through the stage: without the
removal in D(l) of full circles (:func:`cwproc.physics.removed_share.circle_removed_d`)
eps read 0.955 (24 rays) and 0.976 (36 rays) at mu 0.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from scipy import optimize

from cwproc.physics import noise, spectra
from cwproc.physics.geometry import beam_unit_vector
from cwproc.sim import exact_gaussian as eg
from cwproc.stages.epsilon import estimate_epsilon
from cwproc.stages.structure import lag_count

PHI, HEIGHT, EPS, SCALE, NOISE, N_SCANS = 35.0, 100.0, 0.01, 200.0, 0.05, 10
RANGE = HEIGHT / np.sin(np.radians(PHI))
SETTINGS = {"points_per_gate": 10, "pulses_per_ray": 20000, "velocity_resolution_m_s": 0.0382}


def snr_for(sigma_e: float) -> float:
    """The SNR whose predicted noise (Pearson et al. (2009), eq. 3) is ``sigma_e``."""
    band = noise.bandwidth_from_resolution(SETTINGS["velocity_resolution_m_s"])

    def excess(log_snr: float) -> float:
        return float(
            noise.velocity_noise_std(
                10.0**log_snr, SETTINGS["points_per_gate"], SETTINGS["pulses_per_ray"], band
            )
            - sigma_e
        )

    return 10.0 ** optimize.brentq(excess, -4.0, 2.0)


def expected_statistics(pattern: eg.ScanPattern, n_lags: int) -> tuple[np.ndarray, float]:
    """E[D(l)] over the pairs within each scan and E[variance] of V'_L, at rest."""
    cov = eg.block_covariance(
        pattern, N_SCANS, elevation_deg=PHI, range_m=RANGE, epsilon=EPS, outer_scale_m=SCALE
    )
    cov = cov + NOISE**2 * np.eye(cov.shape[0])
    beams = beam_unit_vector(np.asarray(pattern.azimuth_deg), PHI)
    mean_fit = np.tile(np.linalg.pinv(beams), (1, N_SCANS)) / N_SCANS
    keep = np.eye(cov.shape[0]) - np.tile(beams, (N_SCANS, 1)) @ mean_fit
    res = keep @ cov @ keep.T
    m = pattern.n_rays
    d = []
    for lag in range(1, n_lags + 1):
        a = np.concatenate([s * m + np.arange(m - lag) for s in range(N_SCANS)])
        b = a + lag
        d.append(np.mean(res[a, a] + res[b, b] - 2 * res[a, b]))
    n = res.shape[0]
    variance = np.trace((np.eye(n) - np.ones((n, n)) / n) @ res) / (n - 1)
    return np.array(d), float(variance)


def structure_dataset(d: np.ndarray, variance: float, step: float, period: float) -> xr.Dataset:
    """One block at one height in the schema of the structure stage (wind at rest)."""
    lags = np.arange(1, d.size + 1)
    return xr.Dataset(
        {
            "structure_function": (("time", "height", "lag"), d[None, None]),
            "n_pairs": (("time", "height", "lag"), np.full((1, 1, d.size), 2000)),
            "radial_velocity_variance": (("time", "height"), [[variance]]),
            "wind_speed": (("time", "height"), [[0.0]]),
            "snr_median": (("time", "height"), [[snr_for(NOISE)]]),
            "azimuth_step": ("time", [step]),
            "scan_period": ("time", [period]),
            "scan_interval": ("time", [period]),
            "n_scans": ("time", [N_SCANS]),
        },
        coords={
            "time": [np.datetime64("2024-06-01T00:05", "ns")],
            "height": [HEIGHT],
            "range": ("height", [RANGE]),
            "lag": lags,
            "elevation": ("time", [PHI]),
        },
        attrs={"swept_rays": 0, **SETTINGS},
    )


@pytest.mark.parametrize(
    ("rays", "period"),
    [(24, 48.0), pytest.param(36, 54.0, marks=pytest.mark.slow)],
)
def test_vad_eps_from_exact_expected_statistics_within_one_and_a_half_percent(
    rays, period, tmp_path
):
    step = 360.0 / rays
    n_lags = lag_count(step, 9.0)  # the preset's lags: 3 for these coarse scans
    d, variance = expected_statistics(eg.conical_pattern(rays, period, continuous=False), n_lags)
    out = estimate_epsilon(
        structure_dataset(d, variance, step, period),
        lag_number=3,
        model="von_karman",
        table_options={
            "cache_dir": str(tmp_path),
            "height_range_m": (80.0, 130.0),
            "mu_max": 3.0,
            "outer_scale_range_m": (60.0, 700.0),
        },
    )
    # measured: 0.995 (24 rays), 0.996 (36 rays); L_V 1.01
    assert float(out["epsilon"][0, 0]) == pytest.approx(EPS, rel=0.015)
    assert float(out["integral_scale"][0, 0]) == pytest.approx(SCALE, rel=0.05)
    truth = spectra.variance_from(EPS, SCALE, "von_karman")
    assert float(out["velocity_variance"][0, 0]) == pytest.approx(truth, rel=0.03)
