"""The compiled sums of the least-squares VAD fit (cwproc/stages/_vadsums.c) against numpy's
and against a known wind (Smalikho (2020), eq. 1)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cwproc.physics.geometry import beam_unit_vector
from cwproc.stages import vad_fit

_vadsums = pytest.importorskip(
    "cwproc.stages._vadsums", reason="the optional compiled VAD sums were not built (setup.py)"
)

#: the sums of up to 60 rays agree to this share of their largest term (another order)
ROUND_OFF = 1e-12


def scans(rng: np.random.Generator, n_scan: int, n_ray: int, n_gate: int, share: float):
    """Velocities (NaN in some entries that are not valid), a 75 deg VAD design, a mask."""
    azimuth = rng.uniform(0.0, 360.0, (n_scan, n_ray))
    design = beam_unit_vector(azimuth, np.full_like(azimuth, 75.0))
    velocity = rng.normal(0.0, 5.0, (n_scan, n_ray, n_gate))
    valid = rng.random(velocity.shape) < share
    velocity[~valid & (rng.random(velocity.shape) < 0.5)] = np.nan
    return velocity, design, valid


def close(a: np.ndarray, b: np.ndarray, scale: float) -> bool:
    return np.array_equal(np.isnan(a), np.isnan(b)) and bool(
        np.all(np.abs(a - b)[~np.isnan(b)] <= ROUND_OFF * scale)
    )


@settings(max_examples=60, deadline=None)
@given(
    n_scan=st.integers(0, 4),
    n_ray=st.integers(0, 60),
    n_gate=st.integers(0, 40),
    share=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_compiled_sums_equal_numpy_sums(n_scan, n_ray, n_gate, share, seed):
    velocity, design, valid = scans(np.random.default_rng(seed), n_scan, n_ray, n_gate, share)
    ata, aty, n = vad_fit.normal_sums(velocity, design, valid)
    ata0, aty0, n0 = vad_fit.normal_sums_numpy(velocity, design, valid)
    assert np.array_equal(n, n0)  # counts are exact
    assert close(ata, ata0, max(n_ray, 1)) and close(aty, aty0, 25.0 * max(n_ray, 1))
    beta = np.random.default_rng(seed + 1).normal(0.0, 5.0, (n_scan, n_gate, 3))
    beta[..., 0][np.random.default_rng(seed + 2).random((n_scan, n_gate)) < 0.1] = np.nan
    ssr = vad_fit.residual_ssr(velocity, design, valid, beta)
    ssr0 = vad_fit.residual_ssr_numpy(velocity, design, valid, np.nan_to_num(beta))
    assert close(ssr, ssr0, 1000.0 * max(n_ray, 1))


def test_known_wind_recovered_by_both_sums(monkeypatch):
    """A noise-free VAD of a known wind: both sums give it back, with zero residual."""
    rng = np.random.default_rng(3)
    velocity, design, valid = scans(rng, 3, 36, 5, 0.9)
    wind = np.array([4.0, -3.0, 0.5])
    velocity = np.where(valid, np.einsum("srk,k->sr", design, wind)[..., None], np.nan)
    compiled = vad_fit.fit_linear(velocity, design, valid, residuals=False)
    monkeypatch.setattr(vad_fit, "_vadsums", None)
    plain = vad_fit.fit_linear(velocity, design, valid)
    for fit in (compiled, plain):
        np.testing.assert_allclose(fit.beta, np.broadcast_to(wind, fit.beta.shape), atol=1e-12)
        np.testing.assert_allclose(fit.residual_std, 0.0, atol=1e-12)
        assert np.array_equal(fit.n_rays, valid.sum(axis=1))
    assert compiled.residuals is None and plain.residuals.shape == velocity.shape
    np.testing.assert_allclose(compiled.covariance, plain.covariance, atol=1e-20)


def test_residuals_do_not_change_the_fit():
    """Asking for the residuals of every ray adds them, and changes nothing else."""
    velocity, design, valid = scans(np.random.default_rng(4), 2, 24, 7, 0.8)
    with_all = vad_fit.fit_linear(velocity, design, valid)
    without = vad_fit.fit_linear(velocity, design, valid, residuals=False)
    for name in ("beta", "covariance", "residual_std", "n_rays", "determined"):
        assert np.array_equal(getattr(with_all, name), getattr(without, name), equal_nan=True)
    ssr = np.nansum(np.where(valid, with_all.residuals, np.nan) ** 2, axis=1)
    dof = with_all.n_rays - 3
    np.testing.assert_allclose(with_all.residual_std**2, ssr / dof, rtol=1e-12)


def test_groups_with_fewer_than_three_rays_are_not_determined():
    velocity, design, valid = scans(np.random.default_rng(5), 1, 12, 3, 1.0)
    valid[0, 2:, 0] = False  # two rays in gate 0
    valid[0, :, 1] = False  # none in gate 1
    fit = vad_fit.fit_linear(velocity, design, valid)
    assert list(fit.determined[0]) == [False, False, True]
    assert np.all(np.isnan(fit.beta[0, :2])) and np.all(np.isfinite(fit.beta[0, 2]))
    assert list(fit.n_rays[0]) == [2, 0, 12]


def test_short_buffers_are_refused():
    velocity, design, valid = scans(np.random.default_rng(6), 2, 5, 3, 1.0)
    ata, aty, n = np.empty((2, 3, 3, 3)), np.empty((2, 3, 3)), np.empty((2, 2))  # n short
    with pytest.raises(ValueError, match="smaller than its shape"):
        _vadsums.normal_sums(velocity, design, valid, ata, aty, n, 2, 5, 3)
    with pytest.raises(ValueError, match=">= 0"):
        _vadsums.residual_ssr(velocity, design, valid, aty, n, -1, 5, 3)
