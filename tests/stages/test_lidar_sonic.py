"""Matching lidar blocks to sonic windows (stage ``lidar_sonic``) with exact expectations."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.stages.lidar_sonic import compare_lidar_sonic, ratio_summary

T0 = np.datetime64("2024-06-01T00:00:00", "ns")


def sonic_product(eps: np.ndarray, err: np.ndarray) -> xr.Dataset:
    starts = T0 + np.arange(eps.size) * np.timedelta64(1800, "s")
    return xr.Dataset(
        {
            "epsilon": (("window",), eps),
            "epsilon_error": (("window",), err),
            "mean_wind_speed": (("window",), np.linspace(3, 9, eps.size)),
            "stability_parameter": (("window",), np.linspace(-0.5, 0.2, eps.size)),
        },
        coords={"time": (("window",), starts)},
        attrs={"window_s": 1800.0},
    )


def lidar_product(per_window: np.ndarray, blocks: int = 3) -> xr.Dataset:
    """Blocks of 10 min (``blocks`` per 30-min window); gate heights 10, 40, 70 m;
    the 40-m gate holds ``per_window`` times 0.8, 1.0, 1.2 over each window's blocks."""
    n = per_window.size * blocks
    times = T0 + np.arange(n) * np.timedelta64(600, "s") + np.timedelta64(60, "s")
    factors = np.tile(np.linspace(0.8, 1.2, blocks), per_window.size)
    eps = np.repeat(per_window, blocks) * factors
    col = np.stack([np.full(n, 1e-5), eps, np.full(n, 1e-1)], axis=1)
    return xr.Dataset(
        {
            "epsilon": (("time", "height"), col),
            "epsilon_standard_error": (("time", "height"), 0.1 * col),
            "turbulence_flag": (("time", "height"), np.zeros((n, 3), dtype=np.int16)),
        },
        coords={"time": times, "height": [10.0, 40.0, 70.0]},
    )


def test_blocks_of_a_window_are_averaged_and_the_ratio_has_its_error():
    eps_s = np.array([1e-3, 4e-3, 2e-2])
    sonic = sonic_product(eps_s, 0.05 * eps_s)
    lidar = lidar_product(1.5 * eps_s)
    out = compare_lidar_sonic(lidar, sonic, height_m=45.0)
    assert float(out["lidar_height"]) == 40.0
    np.testing.assert_array_equal(out["n_lidar_blocks"].values, [3, 3, 3])
    np.testing.assert_allclose(out["lidar_sonic_epsilon_ratio"].values, 1.5)
    # blocks' errors 0.1 x (0.8, 1.0, 1.2) x 1.5 eps: sqrt(sum squares)/3
    se_l = 0.1 * 1.5 * eps_s * np.sqrt(0.8**2 + 1 + 1.2**2) / 3
    np.testing.assert_allclose(out["lidar_epsilon_standard_error"].values, se_l)
    rel = np.sqrt((se_l / (1.5 * eps_s)) ** 2 + 0.05**2)
    np.testing.assert_allclose(out["lidar_sonic_epsilon_ratio_error"].values, 1.5 * rel)
    assert out.attrs["summary_ratio_geometric_mean"] == pytest.approx(1.5)
    assert out.attrs["summary_n_pairs"] == 3


def test_flagged_blocks_are_left_out_and_an_empty_window_has_no_ratio():
    eps_s = np.array([1e-3, 4e-3])
    lidar = lidar_product(eps_s)
    flag = lidar["turbulence_flag"].values
    flag[0, 1] = 8  # first block of window 0 (factor 0.8): fit failed
    flag[1, 1] = 32  # noise from the prediction: epsilon usable
    flag[3:6, 1] = 1  # all of window 1
    out = compare_lidar_sonic(lidar, sonic_product(eps_s, 0.05 * eps_s), height_m=40.0)
    np.testing.assert_array_equal(out["n_lidar_blocks"].values, [2, 0])
    strict = compare_lidar_sonic(
        lidar, sonic_product(eps_s, 0.05 * eps_s), height_m=40.0, exclude_flag_mask=255
    )
    np.testing.assert_array_equal(strict["n_lidar_blocks"].values, [1, 0])
    assert out["lidar_epsilon"].values[0] == pytest.approx(1e-3 * (1.0 + 1.2) / 2)
    assert np.isnan(out["lidar_sonic_epsilon_ratio"].values[1])


def test_no_lidar_height_near_the_sonic_is_an_error_naming_both_heights():
    eps_s = np.array([1e-3])
    with pytest.raises(CwprocError, match="nearest height to 120 m is 70 m"):
        compare_lidar_sonic(lidar_product(eps_s), sonic_product(eps_s, eps_s), height_m=120.0)


def test_ratio_summary_of_a_lognormal_sample():
    rng = np.random.default_rng(0)
    q = np.exp(rng.normal(np.log(0.8), 0.3, 4000))
    s = ratio_summary(q, 0.1 * q)
    assert s["ratio_geometric_mean"] == pytest.approx(0.8, rel=3 * 0.3 / np.sqrt(4000))
    assert s["log10_ratio_std"] == pytest.approx(0.3 / np.log(10), rel=0.05)
