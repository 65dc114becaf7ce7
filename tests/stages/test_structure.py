"""Azimuth structure function (Smalikho (2020), eqs. 1-2) on scans with known content."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.physics.geometry import radial_velocity
from cwproc.stages.structure import azimuth_structure_function, lag_count

U0, V0, W0 = 6.0, -3.0, 0.2  # m s-1
ELEVATION = 35.3  # deg
RANGES = np.array([200.0, 230.0, 260.0])  # m


def ramp_scans(
    *,
    n_scans: int = 12,
    rays: int = 120,
    period_s: float = 60.0,
    start_az: float = 100.0,
    clockwise: bool = False,
    slope: float = 0.01,
    wind: tuple[float, float, float] = (U0, V0, W0),
) -> xr.Dataset:
    """Scans of V_r = S . V0 + slope * m (m = ray number within the scan).

    With the true wind as the block mean, V'_L = slope * m exactly, so
    D_L(l) = (slope l)^2 and the variance of V'_L is slope^2 M (M + 1) / 12.
    """
    m = np.tile(np.arange(rays), n_scans)
    scan = np.repeat(np.arange(n_scans), rays).astype(np.int64)
    sign = 1.0 if clockwise else -1.0
    az = (start_az + sign * 360.0 * m / rays) % 360.0
    t = np.datetime64("2024-05-01T00:00:00", "ns") + (
        np.arange(m.size) * period_s / rays * 1e9
    ).astype("timedelta64[ns]")
    vr = radial_velocity(*wind, az[:, None], ELEVATION) + slope * m[:, None] + 0 * RANGES
    return xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), vr),
            "qc_flag_radial": (("ray", "range"), np.zeros(vr.shape, dtype=np.int8)),
        },
        coords={
            "time": ("ray", t),
            "azimuth": ("ray", az),
            "elevation": ("ray", np.full(m.size, ELEVATION)),
            "range": ("range", RANGES),
            "scan": ("ray", scan),
        },
        attrs={"homodyne": 0, "instrument": "test", "wind": wind},
    )


def true_wind(ds: xr.Dataset) -> xr.Dataset:
    """A wind product (stage vad schema) holding the true wind for every scan."""
    scans = np.unique(ds["scan"].values)
    times = np.array(
        [ds["time"].values[ds["scan"].values == s].astype("int64").mean() for s in scans]
    ).astype("datetime64[ns]")
    shape = (scans.size, RANGES.size)
    u, v, w = ds.attrs["wind"]
    return xr.Dataset(
        {
            "u": (("time", "height"), np.full(shape, u)),
            "v": (("time", "height"), np.full(shape, v)),
            "w": (("time", "height"), np.full(shape, w)),
        },
        coords={
            "time": ("time", times),
            "height": ("height", RANGES * np.sin(np.deg2rad(ELEVATION))),
            "range": ("height", RANGES),
            "scan": ("time", scans),
            "elevation": ("time", np.full(scans.size, ELEVATION)),
        },
    )


def test_ramp_gives_exact_structure_function_and_pair_counts():
    ds = ramp_scans()
    sf = azimuth_structure_function(ds, true_wind(ds), n_scans=6, max_lag_deg=9.0)
    # dtheta = 3 deg -> lags 1..3 (3 l <= 9)
    np.testing.assert_array_equal(sf["lag"].values, [1, 2, 3])
    expected = (0.01 * sf["lag"].values) ** 2
    np.testing.assert_allclose(
        sf["structure_function"].values, np.broadcast_to(expected, (2, 3, 3)), rtol=1e-9
    )
    # eq. 2: M - l pairs per scan, N scans per block
    np.testing.assert_array_equal(sf["n_pairs"].values[0, 0], 6 * (120 - np.array([1, 2, 3])))
    np.testing.assert_allclose(sf["azimuth_step"].values, 3.0)
    np.testing.assert_allclose(sf["scan_period"].values, 60.0, rtol=1e-6)
    # consecutive full circles: the scans start one scan period apart
    np.testing.assert_allclose(sf["scan_interval"].values, 60.0, rtol=1e-6)
    np.testing.assert_allclose(sf["wind_speed"].values, np.hypot(U0, V0))
    # pooled over the 6 x 120 values of the block, ddof = 1
    pooled = 0.01**2 * (120**2 - 1) / 12 * 720 / 719
    np.testing.assert_allclose(sf["radial_velocity_variance"].values, pooled, rtol=1e-9)
    np.testing.assert_array_equal(sf["n_scans"].values, [6, 6])
    assert sf["structure_function"].dims == ("time", "height", "lag")


def test_clockwise_and_start_azimuth_do_not_matter():
    a = ramp_scans(clockwise=True, start_az=0.0)
    b = ramp_scans(clockwise=False, start_az=217.0)
    sa = azimuth_structure_function(a, true_wind(a), n_scans=12, max_lag_deg=9.0)
    sb = azimuth_structure_function(b, true_wind(b), n_scans=12, max_lag_deg=9.0)
    np.testing.assert_allclose(sa["structure_function"], sb["structure_function"], rtol=1e-9)


def test_missing_and_flagged_rays_are_skipped_pairwise():
    ds = ramp_scans(n_scans=4)
    drop = np.zeros(ds.sizes["ray"], dtype=bool)
    drop[[5, 130, 131]] = True  # scan 0 ray 5; scan 1 rays 10, 11
    flags = ds["qc_flag_radial"].values.copy()
    flags[250, :] = 1  # scan 2 ray 10 low SNR
    ds["qc_flag_radial"] = (("ray", "range"), flags)
    ds = ds.isel(ray=~drop)
    sf = azimuth_structure_function(ds, true_wind(ds), n_scans=4, max_lag_deg=9.0)
    # the ramp survives exactly; lost pairs: each missing ray kills up to 2 pairs per lag
    np.testing.assert_allclose(sf["structure_function"].values[0, 0], (0.01 * np.arange(1, 4)) ** 2)
    full = 4 * (120 - np.arange(1, 4))
    lost_lag1 = 2 + 3 + 2  # isolated ray: 2; adjacent pair: 3 (10-11 counted once); flagged: 2
    assert sf["n_pairs"].values[0, 0, 0] == full[0] - lost_lag1
    assert sf["n_pairs"].values[0, 0, 1] == full[1] - (2 + 4 + 2)


def test_blind_sector_reduces_pairs_only():
    ds = ramp_scans(n_scans=3, clockwise=True, start_az=0.0)
    keep = ~((ds["azimuth"].values >= 90.0) & (ds["azimuth"].values < 150.0))  # 20 rays
    ds = ds.isel(ray=keep)
    sf = azimuth_structure_function(ds, true_wind(ds), n_scans=3, max_lag_deg=9.0)
    np.testing.assert_allclose(sf["structure_function"].values[0, 1], (0.01 * np.arange(1, 4)) ** 2)
    # pairs (m, m+l) with both ends outside m = 30..49
    m = np.arange(120)
    inside = (m >= 30) & (m < 50)
    expected = [3 * np.sum(~inside[:-lag] & ~inside[lag:]) for lag in (1, 2, 3)]
    np.testing.assert_array_equal(sf["n_pairs"].values[0, 1], expected)


def test_white_noise_structure_function_is_twice_the_variance():
    rng = np.random.default_rng(42)
    ds = ramp_scans(n_scans=20, slope=0.0)
    sigma = 0.3
    ds["radial_velocity"] = ds["radial_velocity"] + sigma * rng.standard_normal(
        ds["radial_velocity"].shape
    )
    sf = azimuth_structure_function(ds, true_wind(ds), n_scans=20, max_lag_deg=9.0)
    # 2 sigma^2 at every lag (Smalikho (2020), eq. 4 with eps = 0); ~2400 pairs -> 3 % 1-sigma
    np.testing.assert_allclose(sf["structure_function"].values, 2 * sigma**2, rtol=0.12)
    np.testing.assert_allclose(sf["radial_velocity_variance"].values, sigma**2, rtol=0.08)


def test_block_partition_keeps_short_last_block():
    ds = ramp_scans(n_scans=25)
    sf = azimuth_structure_function(ds, true_wind(ds), n_scans=10, max_lag_deg=6.0, min_lags=2)
    np.testing.assert_array_equal(sf["n_scans"].values, [10, 10, 5])
    np.testing.assert_array_equal(sf["lag"].values, [1, 2])
    assert np.all(np.diff(sf["time"].values) > np.timedelta64(0, "s"))


def test_homodyne_magnitudes_take_the_sign_of_the_mean_wind():
    # a wind whose radial component never crosses zero: |V_r| carries all information
    wind = (1.0, 0.5, 4.0)
    ds = ramp_scans(wind=wind, slope=0.005)
    signed = azimuth_structure_function(ds, true_wind(ds), n_scans=12, max_lag_deg=9.0)
    homo = ds.copy()
    homo["radial_velocity"] = -np.abs(homo["radial_velocity"])  # sign lost
    homo.attrs["homodyne"] = 1
    sf = azimuth_structure_function(homo, true_wind(ds), n_scans=12, max_lag_deg=9.0)
    np.testing.assert_allclose(sf["structure_function"], signed["structure_function"], rtol=1e-9)


@pytest.mark.parametrize("spelling", ["false", "FALSE ", "0", 0, False])
def test_homodyne_false_in_any_spelling_is_heterodyne(spelling):
    """``bool("false")`` is True: the attribute goes through the one parser instead."""
    ds = ramp_scans()  # the default wind's V_r changes sign round the circle
    signed = azimuth_structure_function(ds, true_wind(ds))
    ds.attrs["homodyne"] = spelling
    sf = azimuth_structure_function(ds, true_wind(ds))
    xr.testing.assert_identical(sf, signed)
    assert sf.attrs["homodyne"] == 0
    # read as homodyne, the signs near the zero crossings are dropped: a different result
    ds.attrs["homodyne"] = "true"
    homo = azimuth_structure_function(ds, true_wind(ds))
    assert homo.attrs["homodyne"] == 1
    assert np.all(homo["n_pairs"].values < signed["n_pairs"].values)
    # an explicit argument overrides the attribute
    explicit = azimuth_structure_function(ds, true_wind(ds), homodyne=False)
    np.testing.assert_array_equal(explicit["structure_function"], signed["structure_function"])


def test_unreadable_homodyne_attribute_is_a_clear_error():
    ds = ramp_scans(n_scans=2)
    ds.attrs["homodyne"] = "maybe"
    with pytest.raises(CwprocError, match="homodyne is 'maybe': expected 0/1, true/false"):
        azimuth_structure_function(ds, true_wind(ds), n_scans=2)


def test_impossible_inputs_raise_cwproc_errors():
    ds = ramp_scans(n_scans=2)
    wind = true_wind(ds)
    with pytest.raises(CwprocError, match="qc"):
        azimuth_structure_function(ds.drop_vars("qc_flag_radial"), wind, n_scans=2, max_lag_deg=9.0)
    with pytest.raises(CwprocError, match="no conical-scan ray"):
        azimuth_structure_function(
            ds, wind.assign_coords(scan=("time", [7, 8])), n_scans=2, max_lag_deg=9.0
        )
    with pytest.raises(CwprocError, match="gates"):
        azimuth_structure_function(
            ds, wind.assign_coords(range=("height", RANGES + 7.0)), n_scans=2, max_lag_deg=9.0
        )
    # 90 deg steps: not one lag within 60 deg (a 12-ray VAD gets its two, 30 and 60 deg)
    coarse = ramp_scans(n_scans=2, rays=4)
    with pytest.raises(CwprocError, match="max_lag_deg"):
        azimuth_structure_function(coarse, true_wind(coarse), n_scans=2, max_lag_deg=9.0)


def test_chunked_blocks_give_the_same_result(monkeypatch):
    import cwproc.stages.structure as structure

    rng = np.random.default_rng(3)
    ds = ramp_scans(n_scans=25)
    ds["radial_velocity"] = ds["radial_velocity"] + 0.2 * rng.standard_normal(
        ds["radial_velocity"].shape
    )
    whole = azimuth_structure_function(ds, true_wind(ds), n_scans=4, max_lag_deg=9.0)
    monkeypatch.setattr(structure, "_CHUNK_VALUES", 1)  # one block per chunk
    chunked = azimuth_structure_function(ds, true_wind(ds), n_scans=4, max_lag_deg=9.0)
    xr.testing.assert_identical(whole, chunked)


def test_homodyne_sign_from_the_model_and_rays_near_zero_crossings_left_out():
    """|V_r| gets the sign of S . <V>_N; rays with |m| < 1 m/s + 3 sigma' become NaN."""
    from cwproc.stages.structure import homodyne_radial_velocity

    rng = np.random.default_rng(4)
    theta = np.deg2rad(np.arange(0.0, 360.0, 2.0))
    model = np.repeat((6.0 * np.sin(theta))[None, :], 20, axis=0).ravel()[:, None]
    true = model + 0.5 * rng.standard_normal(model.shape)
    block = np.repeat(np.arange(2), model.size // 2)
    out = homodyne_radial_velocity(np.abs(true), model, block)
    kept = np.isfinite(out[:, 0])
    # the threshold 1 + 3 x 0.5 = 2.5 m/s (sigma' within 10 %) leaves |sin| > 0.42 only
    assert np.all(np.abs(model[kept, 0]) >= 2.5 * 0.9)
    assert np.all(~kept[np.abs(model[:, 0]) < 2.5 * 1.1 - 0.5])
    # kept rays carry the true sign: no folding error above 3 sigma
    np.testing.assert_allclose(out[kept, 0], true[kept, 0], rtol=1e-12)
    # the share left out: 2 asin(2.5/6) / pi = 27.5 %
    assert np.mean(~kept) == pytest.approx(2 * np.arcsin(2.5 / 6) / np.pi, abs=0.04)


def test_coarse_scans_get_three_lags_beyond_nine_degrees():
    # 24 rays (15 deg): lags 1-3 (45 deg) from the exact two-beam model, not none
    ds = ramp_scans(n_scans=4, rays=24)
    sf = azimuth_structure_function(ds, true_wind(ds), n_scans=4, max_lag_deg=9.0)
    np.testing.assert_array_equal(sf["lag"].values, [1, 2, 3])
    np.testing.assert_allclose(sf["azimuth_step"].values, 15.0)
    # V'_L = slope m: D_L(l) = (slope l)^2 at any step
    np.testing.assert_allclose(sf["structure_function"].values[0, 0], (0.01 * np.arange(1, 4)) ** 2)


def test_pair_azimuth_weights_full_circle_and_sector():
    from cwproc.physics.atable_interp import azimuth_bin_weights

    ds = ramp_scans(n_scans=4, rays=72)
    sf = azimuth_structure_function(ds, true_wind(ds), n_scans=4, max_lag_deg=9.0)
    assert sf["pair_azimuth_weights"].dims == ("time", "height", "lag", "azimuth_node")
    w = sf["pair_azimuth_weights"].values[0, 0, 0]
    assert w.sum() == pytest.approx(1.0)
    # a full circle spreads the pairs evenly over the nodes (71 pairs of 72 rays)
    np.testing.assert_allclose(w, 1 / w.size, atol=0.3 / w.size)  # no wrap-around pair
    # lag l: 72 - l pairs centred l/2 steps on from the first ray
    wind_to = float(sf["wind_to_direction"].values[0, 0])
    az0 = float(ds["azimuth"].values[0])
    sign = 1.0 if (ds["azimuth"].values[1] - az0) % 360.0 < 180.0 else -1.0
    for lag in (2, 3):
        mids = az0 + sign * 5.0 * (np.arange(72 - lag) + 0.5 * lag)
        expected = azimuth_bin_weights(np.radians(sign * (wind_to - mids)))
        got = sf["pair_azimuth_weights"].values[0, 0, lag - 1]
        np.testing.assert_allclose(got, expected, atol=1e-9)
    # a 90 deg sector: only the rays from 100 deg down to 10 deg (anticlockwise)
    az = ds["azimuth"].values
    keep = ((100.0 - az) % 360.0) <= 90.0
    sector = ds.isel(ray=np.flatnonzero(keep))
    sf_s = azimuth_structure_function(sector, true_wind(ds), n_scans=4, max_lag_deg=9.0)
    ws = sf_s["pair_azimuth_weights"].values[0, 0, 0]
    wind_to = float(sf_s["wind_to_direction"].values[0, 0])
    mids = 100.0 - 5.0 * (np.arange(18) + 0.5)
    expected = azimuth_bin_weights(np.radians(-(wind_to - mids)))
    np.testing.assert_allclose(ws, expected, atol=1e-9)
    assert np.count_nonzero(ws > 0) <= 11


def test_statistics_covariance_is_the_scatter_of_the_scan_means():
    """Per block: the sample covariance over its scans of (D_L(1..L), variance) / n.

    Scans with any missing statistic are left out; a block with one scan gets NaN.
    """
    from cwproc.physics.block_stats import block_statistics

    rng = np.random.default_rng(4)
    vprime = rng.normal(0.0, 1.0, (13, 36, 2))  # blocks of 6, 6 and 1 scans
    vprime[2, :, 1] = np.nan  # scan 2 has nothing at the second height
    *_, cov = block_statistics(vprime, 6, 3)
    assert cov.shape == (3, 2, 4, 4)
    for b, h in ((0, 0), (0, 1), (1, 0)):
        per_scan = []
        for s in range(6 * b, 6 * b + 6):
            v = vprime[s, :, h]
            if np.all(np.isnan(v)):
                continue
            stats = [np.mean((v[lag:] - v[:-lag]) ** 2) for lag in (1, 2, 3)]
            per_scan.append([*stats, np.mean(v**2)])
        per_scan = np.array(per_scan)
        expected = np.cov(per_scan, rowvar=False) / len(per_scan)
        np.testing.assert_allclose(cov[b, h], expected, rtol=1e-10)
    assert np.all(np.isnan(cov[2]))


def test_pair_node_weights_are_the_dense_azimuth_bin_weights():
    """The node weights summed per node equal azimuth_bin_weights to the bit, with NaN
    azimuths, positions without pairs and a height without any pair (NaN)."""
    from cwproc.physics.atable_interp import azimuth_bin_weights
    from cwproc.stages.structure import pair_node_weights

    rng = np.random.default_rng(5)
    theta = rng.uniform(-10.0, 10.0, (3, 179, 40))
    theta[0, 5, 3] = np.nan
    theta[1, :, 7] = np.nan
    counts = rng.integers(0, 11, theta.shape).astype(float)
    counts[2, :, 9] = 0.0
    got = pair_node_weights(theta, counts)
    assert np.array_equal(got, azimuth_bin_weights(theta, axis=1, counts=counts), equal_nan=True)
    assert np.isnan(got[1, 7]).all() and np.isnan(got[2, 9]).all()
    assert np.allclose(np.nansum(got, axis=-1)[~np.isnan(got[..., 0])], 1.0)


def test_block_median_is_numpy_nanmedian():
    """The block SNR median (partitions, NaN last) equals numpy.nanmedian over scans and
    azimuths to the bit: odd and even counts, a column with one value, one without any
    (NaN), a short last block."""
    import warnings

    from cwproc.stages.structure import block_median

    rng = np.random.default_rng(11)
    values = rng.lognormal(size=(25, 18, 7))
    values[rng.random(values.shape) < 0.3] = np.nan
    values[:, :, 2] = np.nan
    values[:10, :, 3] = np.nan
    values[3, 4, 3] = 0.5
    got = block_median(values, 10)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        expected = [np.nanmedian(values[k : k + 10].reshape(-1, 7), axis=0) for k in (0, 10, 20)]
    assert np.array_equal(got, np.array(expected), equal_nan=True)
    assert np.isnan(got[:, 2]).all() and got[0, 3] == 0.5


def test_group_median_is_the_grouped_median_of_pandas():
    """The per-block median of the scan period and interval (NaN skipped, NaN for a
    block without values) equals pandas' grouped median, reindexed to every block, to
    the bit: odd and even counts, one value, an infinite one, a block without any."""
    import pandas as pd

    from cwproc.physics.block_stats import group_median

    rng = np.random.default_rng(12)
    values = np.round(rng.normal(45.0, 0.3, 40), 3)
    values[[3, 17]] = np.nan
    values[25] = np.inf
    group = np.sort(rng.integers(0, 5, 40))
    group[group == 2] = 1  # block 2 has no value
    group[-1] = 6  # block 6 has one
    expected = pd.Series(values).groupby(group).median().reindex(np.arange(8)).to_numpy()
    got = group_median(values, group, 8)
    assert np.array_equal(got, expected, equal_nan=True)
    assert np.isnan(got[[2, 5, 7]]).all() and got[6] == values[-1]
    assert np.isnan(group_median(np.full(3, np.nan), np.arange(3), 4)).all()
    shuffled = np.random.default_rng(1).permutation(40)  # groups in any order
    assert np.array_equal(group_median(values[shuffled], group[shuffled], 8), got, True)


def test_pair_azimuth_weights_of_all_lags_at_once_are_those_lag_by_lag():
    """The weights of every lag from one grid of pair middles and one sum per node equal
    :func:`pair_node_weights` of each lag on its own, to the bit (missing values, a
    block without a start azimuth, a height without a wind direction, both rotations,
    more lags than pair positions)."""
    from cwproc.physics.block_stats import pair_azimuth_weights
    from cwproc.stages.structure import pair_node_weights

    rng = np.random.default_rng(31)
    vprime = rng.normal(size=(23, 40, 4))
    vprime[rng.random(vprime.shape) < 0.05] = np.nan
    vprime[2, :, 1] = np.nan
    first_az = np.array([12.0, np.nan, 300.5])
    wind_to = rng.uniform(0.0, 360.0, (3, 4))
    wind_to[0, 2] = np.nan
    starts = np.arange(0, 23, 10)
    finite = np.isfinite(vprime)
    for sign in (1.0, -1.0):
        got = pair_azimuth_weights(vprime, 10, first_az, 9.0, sign, wind_to, 42)
        assert got.shape == (3, 4, 42, 36) and np.isnan(got[:, :, 39:]).all()
        for lag in (1, 2, 7, 39):
            ok = finite[:, lag:] & finite[:, :-lag]
            count = np.add.reduceat(ok.astype(float), starts, axis=0)
            beta = first_az[:, None] + sign * 9.0 * (np.arange(40 - lag) + 0.5 * lag)
            theta = np.radians(sign * (wind_to[:, None, :] - beta[:, :, None]))
            expected = pair_node_weights(theta, count).astype(np.float32)
            assert got[:, :, lag - 1].tobytes() == expected.tobytes()


def test_rays_out_of_order_give_the_same_structure_function():
    """Rays stored out of time order (placed on the grid one by one) and in order (the
    grid taken as it is): the same dataset, bit for bit."""
    ds = ramp_scans(n_scans=20, rays=36)
    ds["radial_velocity"][:] += np.random.default_rng(32).normal(
        0.0, 0.3, ds["radial_velocity"].shape
    )
    wind = true_wind(ds)
    shuffled = ds.isel(ray=np.random.default_rng(33).permutation(ds.sizes["ray"]))
    in_order = azimuth_structure_function(ds, wind, n_scans=10)
    out_of_order = azimuth_structure_function(shuffled, wind, n_scans=10)
    assert in_order.identical(out_of_order)


def test_a_missing_ray_is_a_flagged_ray():
    """A ray absent from the scans (the grid filled ray by ray) and the same ray flagged
    (the complete grid taken as it is) give the same statistics, bit for bit."""
    ds = ramp_scans(n_scans=20, rays=36)
    noise = np.random.default_rng(34).normal(0.0, 0.3, ds["radial_velocity"].shape)
    ds["radial_velocity"][:] += noise
    wind = true_wind(ds)
    flagged = ds.copy(deep=True)
    flagged["qc_flag_radial"][50] = 1
    dropped = ds.isel(ray=np.delete(np.arange(ds.sizes["ray"]), 50))
    a = azimuth_structure_function(flagged, wind, n_scans=10)
    b = azimuth_structure_function(dropped, wind, n_scans=10)
    for name in (
        "structure_function",
        "n_pairs",
        "radial_velocity_variance",
        "statistics_covariance",
        "pair_azimuth_weights",
    ):
        assert a[name].identical(b[name]), name


def test_block_median_between_bounds_is_numpy_nanmedian():
    """Blocks of 1800 values per height (10 scans of 180 rays): the medians sought
    between two sampled bounds equal numpy.nanmedian to the bit, with missing values,
    ties, infinities, a column without any value, one with a single value, and one whose
    sampled rows are far off (its middle is not between the bounds: partitioned whole)."""
    import warnings

    from cwproc.stages.structure import _median_within_bounds, block_median

    rng = np.random.default_rng(12)
    values = rng.lognormal(size=(20, 180, 8))
    values[rng.random(values.shape) < 0.002] = np.nan
    values[..., 1] = np.round(values[..., 1])  # ties
    values[:10, :, 2] = np.nan
    values[:10, 7, 2] = 0.25
    values[10:, :, 3] = np.nan
    values[:, ::8, 4] += 100.0  # every sampled row far above the others
    values[0, :20, 5] = np.inf
    got = block_median(values, 10)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        expected = [np.nanmedian(values[k : k + 10].reshape(-1, 8), axis=0) for k in (0, 10)]
    assert got.tobytes() == np.array(expected).tobytes()
    first = values[:10].reshape(-1, 8)
    bounded = _median_within_bounds(first, np.count_nonzero(~np.isnan(first), axis=0))
    assert np.isnan(bounded[4]) and np.count_nonzero(np.isnan(bounded)) <= 3


@pytest.mark.parametrize(
    "step, lags",
    # 24/36-ray VADs: min_lags 3 (45/30 deg); 12 rays: the two within 60 deg; 4: none
    [(15.0, 3), (10.0, 3), (30.0, 2), (24.0, 2), (90.0, 0), (1.0, 9)],
)
def test_lag_count_of_coarse_scans_stops_at_60_deg(step, lags):
    assert lag_count(step, 9.0) == lags


@pytest.mark.parametrize("clockwise", [False, True])
def test_scan_start_angle_is_the_first_ray_from_the_wind_in_the_sense_of_rotation(clockwise):
    """``scan_start_angle``: the first ray's azimuth from the direction the block-mean wind
    blows towards, counted in the scan's sense of rotation (the seam's place, on which the
    correlation of consecutive circles at mu near 1 depends)."""
    ds = ramp_scans(start_az=40.0, clockwise=clockwise)
    sf = azimuth_structure_function(ds, true_wind(ds), n_scans=6, max_lag_deg=9.0)
    wind_to = sf["wind_to_direction"].values
    np.testing.assert_allclose(wind_to, np.degrees(np.arctan2(U0, V0)) % 360.0, atol=1e-6)
    expected = ((40.0 - wind_to) * (1.0 if clockwise else -1.0)) % 360.0
    np.testing.assert_allclose(sf["scan_start_angle"].values, expected, atol=1e-6)
