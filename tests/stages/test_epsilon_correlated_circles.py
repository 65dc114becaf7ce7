"""Error bars of consecutive circles that share eddies (issue 29, Show: step-stare at mu 1)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from cwproc.config import load_config
from cwproc.pipeline import process_scans
from cwproc.sim import exact_gaussian as eg
from cwproc.stages import epsilon

PHI = 35.0
HEIGHT = 100.0


def _variance_errors(mu: float, monkeypatch: pytest.MonkeyPatch) -> tuple[np.ndarray, ...]:
    """sigma_V^2 and its standard error of 6 blocks of a 24-ray step-stare VAD (3 s dwell,
    1 s moves, 10 scans, scans from north, wind towards 70 deg), with the correlated-circle
    factor and without it (the jackknife's covariance as it is)."""
    pattern = eg.conical_pattern(24, 96.0, continuous=False, pulses_per_ray=45000, prf_hz=15000.0)
    radius = HEIGHT / np.tan(np.radians(PHI))
    scans = eg.gaussian_scans(
        pattern=pattern,
        n_scans=10,
        n_blocks=6,
        elevation_deg=PHI,
        ranges_m=[HEIGHT / np.sin(np.radians(PHI))],
        epsilon=0.01,
        outer_scale_m=200.0,
        wind_speed_m_s=mu * 2 * np.pi * radius / 96.0,
        wind_direction_deg=250.0,
        noise_std_m_s=0.05,
        seed=3,
    )
    base = load_config("streamline")
    config = dataclasses.replace(
        base, turbulence=dataclasses.replace(base.turbulence, model="von_karman", n_scans=10)
    )
    out = []
    for factor in (True, False):
        if not factor:
            monkeypatch.setattr(epsilon, "correlated_scans_covariance", lambda *a: a[2])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            turb = process_scans(scans, config, [])["turbulence"]
        out.append(turb["velocity_variance_standard_error"].values[:, 0])
    out.append(turb["velocity_variance"].values[:, 0])
    return tuple(out)


def test_the_variance_error_grows_by_the_correlated_circle_factor_at_mu_1(monkeypatch):
    """At mu 1, with the seam near where the beam moves with the wind (the benchmark's
    start angle, 297 deg), the factor of the variance is 1.15-1.2 (point beams): its
    standard error grows by about its root, 1.07-1.10, in every block."""
    with_f, without, var = _variance_errors(1.0, monkeypatch)
    assert np.all(np.isfinite(var))
    ratio = with_f / without
    assert np.all((ratio > 1.04) & (ratio < 1.13)), ratio


def test_no_factor_where_the_transport_is_not_measured(monkeypatch):
    """At rest (mu 0: the generator's scans are independent fields) the measured mu is
    the turbulence's scatter alone: the factor is not applied."""
    with_f, without, _ = _variance_errors(0.0, monkeypatch)
    np.testing.assert_allclose(with_f, without, rtol=0.02)
