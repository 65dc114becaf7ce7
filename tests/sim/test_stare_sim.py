"""Virtual stares: exact statistics match the O'Connor band integral; the daily cycle."""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics import stare as ps
from cwproc.sim.field3d import von_karman_field
from cwproc.sim.stare import daily_cycle, gaussian_stares


@pytest.mark.parametrize(("n_rays", "n_windows"), [(23, 2000), (90, 800)])
def test_exact_stares_have_the_band_variance_of_the_theory(n_rays, n_windows):
    """Mean window variance = eps^(2/3) G (window, ray and gate filters) within 3 SE."""
    ray_s, speed, eps = 4 / 3, 5.0, 1e-2
    w = gaussian_stares(
        n_windows,
        n_rays,
        epsilon=eps,
        noise_std_m_s=0.0,
        seed=3,
        ray_duration_s=ray_s,
        wind_speed_m_s=speed,
    )
    ratio = w.var(axis=1) / (
        eps ** (2 / 3) * ps.band_variance_factor(speed * n_rays * ray_s, speed * ray_s, 15.3, 18.0)
    )
    assert abs(ratio.mean() - 1) < 3 * ratio.std() / np.sqrt(n_windows) + 0.01


def test_daily_cycle_alternates_vads_and_stares_on_one_clock():
    field = von_karman_field((32, 32, 16), 8.0, epsilon=1e-2, integral_scale_m=100.0, seed=1)
    parts = daily_cycle(
        field,
        hours=0.25,
        vad_every_s=300.0,
        vad_rays=24,
        vad_period_s=24.0,
        vad_elevation_deg=35.3,
        ranges_m=np.array([45.0, 75.0]),
        ray_duration_s=4 / 3,
        wind_speed_m_s=5.0,
        wind_direction_deg=240.0,
        noise_std_m_s=0.05,
        seed=2,
    )
    kinds = [p.attrs["scan_type"] for p in parts]
    assert kinds == ["VAD", "Stare"] * 3
    starts = [p["time"].values[0] for p in parts]
    assert all(np.diff(np.array(starts)) > np.timedelta64(0))
    stare = parts[1]
    assert (stare["elevation"].values == 90).all()
    # the stare fills the time from the end of the VAD to the next VAD
    span = (stare["time"].values[-1] - parts[0]["time"].values[0]) / np.timedelta64(1, "s")
    assert 300.0 - 4 / 3 - 1 < span < 300.0
