"""Stare stage: eps of O'Connor et al. (2010) against exact-statistics truth, real stares."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from cwproc.physics.noise import bandwidth_from_resolution, velocity_noise_std
from cwproc.sim.stare import gaussian_stares, stare_windows_dataset
from cwproc.stages.stare import (
    FLAG_NO_WIND,
    FLAG_NOISE_DOMINATED,
    FLAG_TOO_FEW_SAMPLES,
    StareOptions,
    split_stares,
    stare_product,
)

RAY_S = 20000 / 15000.0  # Stream Line: 20000 pulses at 15 kHz
WINDOW_S = 300.0
SNR = 0.02  # -17 dB: sigma_e = 0.14 m/s at 10 points per gate, 20000 pulses


def stare_dataset(w: np.ndarray, snr: float = SNR) -> xr.Dataset:
    """Windows of stare rays (one gate at 300 m) as a canonical scan dataset."""
    return stare_windows_dataset(w, snr, window_s=WINDOW_S, ray_s=RAY_S)


def constant_wind(speed: float) -> xr.Dataset:
    return xr.Dataset(
        {
            "wind_speed": (("time", "height"), np.full((2, 2), speed)),
            "wind_speed_error": (("time", "height"), np.full((2, 2), 0.0)),
        },
        coords={
            "time": np.array(["2024-01-01T00:00", "2024-01-02T00:00"], dtype="datetime64[ns]"),
            "height": [0.0, 1000.0],
        },
    )


@pytest.mark.parametrize("eps", [1e-4, 1e-3, 1e-2, 1e-1])
def test_simulated_truth_recovered(eps):
    """Median stare eps within 20 % of the truth, 200 windows of exact statistics."""
    noise = float(velocity_noise_std(SNR, 6, 20000, bandwidth_from_resolution(0.0382)))
    n_ray = round(WINDOW_S / RAY_S)
    w = gaussian_stares(
        200,
        n_ray,
        epsilon=eps,
        noise_std_m_s=noise,
        seed=7,
        ray_duration_s=RAY_S,
        wind_speed_m_s=5.0,
    )
    product = stare_product(stare_dataset(w), constant_wind(5.0), StareOptions())
    estimate = product["epsilon_stare"].values[:, 0]
    assert np.isfinite(estimate).all()
    assert np.median(estimate) / eps == pytest.approx(1.0, abs=0.2)
    # the noise correction matters: without it eps at 1e-4 would be far too high
    assert product["w_noise_variance"].values[0, 0] == pytest.approx(noise**2, rel=1e-6)


def test_pure_noise_is_flagged_not_turned_into_eps():
    """w = instrument noise only: the noise variance from the SNR takes it all away."""
    noise = float(velocity_noise_std(SNR, 6, 20000, bandwidth_from_resolution(0.0382)))
    w = noise * np.random.default_rng(4).standard_normal((40, 225))
    product = stare_product(stare_dataset(w), constant_wind(5.0), StareOptions())
    flagged = (product["stare_flag"].values[:, 0] & FLAG_NOISE_DOMINATED) != 0
    assert 0.2 < flagged.mean() < 0.8  # the corrected variance scatters about zero
    assert np.isnan(product["epsilon_stare"].values[flagged, 0]).all()
    corrected = product["w_variance_corrected"].values[:, 0]
    assert abs(np.mean(corrected)) < 0.05 * noise**2 * 10


def test_no_wind_gives_w_statistics_and_flag():
    rng = np.random.default_rng(1)
    w = 0.3 * rng.standard_normal((2, 225))
    product = stare_product(stare_dataset(w), None, StareOptions())
    assert np.isnan(product["epsilon_stare"].values).all()
    assert (product["stare_flag"].values & FLAG_NO_WIND).all()
    kept = product["w_ray"].values[:, 0].reshape(w.shape)
    assert np.isfinite(kept).mean() > 0.99  # the outlier screen spares Gaussian w
    np.testing.assert_allclose(product["w_mean"].values[:, 0], np.nanmean(kept, axis=1))
    assert product["w_variance"].values[0, 0] == pytest.approx(0.09, rel=0.2)


def test_split_stares_keeps_the_conical_rays():
    rng = np.random.default_rng(2)
    ds = stare_dataset(rng.standard_normal((1, 10)))
    ds = ds.assign_coords(elevation=("ray", np.r_[np.full(5, 75.0), np.full(5, 90.0)]))
    stares, others = split_stares(ds)
    assert stares.sizes["ray"] == 5 and others.sizes["ray"] == 5
    assert (stares["elevation"].values == 90).all()


@pytest.mark.realdata
def test_real_stares_read_and_processed(real_data):
    from cwproc.io.halo import read_hpl

    for name, gates in (
        ("eriswil-2022-12-14-Stare_91_20221214_11.hpl", 250),
        ("hyytiala-2023-09-13-Stare_46_20230913_23.hpl", 320),
        ("warsaw-2022-12-13-Stare_213_20221213_04.hpl", 333),
    ):
        ds = read_hpl(real_data / "hpl" / name)
        stares, others = split_stares(ds)
        assert others is None and stares.sizes["ray"] == ds.sizes["ray"]
        product = stare_product(stares, constant_wind(5.0), StareOptions())
        assert product.sizes["height"] == gates
        w = product["w_ray"].values
        assert np.isfinite(w).any(), name
        # SNR-screened w of a real stare: most |w| below 1.5 m/s (clear air, Dec/Sep
        # nights); a few gates of Warsaw reach 16 m/s at SNR > 0.008 (not air motion)
        assert np.nanpercentile(np.abs(w), 90) < 1.5, name
        # one or two rays: no variance window holds three, so no eps (flag bit 2, not 4)
        assert np.isnan(product["epsilon_stare"].values).all()
        flag = product["stare_flag"].values
        assert (flag & FLAG_TOO_FEW_SAMPLES).all() and not (flag & FLAG_NOISE_DOMINATED).any()


def test_spikes_are_screened_within_the_variance_window():
    rng = np.random.default_rng(5)
    w = 0.3 * rng.standard_normal((3, 225))
    spiked = w.copy()
    spiked[:, ::40] = 16.0  # the kind of gate a real Warsaw stare has at SNR > 0.008
    clean = stare_product(stare_dataset(w), constant_wind(5.0), StareOptions())
    screened = stare_product(stare_dataset(spiked), constant_wind(5.0), StareOptions())
    rays = (np.arange(3)[:, None] * 225 + np.arange(0, 225, 40)[None, :]).ravel()
    assert np.isnan(screened["w_ray"].values[rays]).all()
    np.testing.assert_allclose(screened["w_variance"].values, clean["w_variance"].values, rtol=0.15)
