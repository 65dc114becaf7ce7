"""Stage sonic_sf: structure-function types of Gladkikh et al. (2014), eqs. 2-7."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from scipy.fft import next_fast_len

from cwproc.config import load_config
from cwproc.errors import CwprocError
from cwproc.physics import sonic_fits
from cwproc.physics import structure_functions as SF
from cwproc.pipeline import process_sonic
from cwproc.sim.sonic import SFModel, default_models, simulate_sonic_dataset
from cwproc.stages import sonic_sf as S
from cwproc.stages import sonic_sf_tables as tables


@pytest.fixture(scope="module")
def sims() -> dict[int, tuple[xr.Dataset, xr.Dataset]]:
    """Four hours (24 windows x 3 components) of each type, and their SF products."""
    out = {}
    for t in (1, 2, 3):
        ds = simulate_sonic_dataset(hours=4, sf_type=t, seed=10 + t)
        out[t] = (ds, S.structure_function_types(ds))
    return out


# ----------------------------------------------------------------------------- pieces


def test_fft_structure_function_equals_direct_sum_with_missing_samples():
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.standard_normal((2, 500)), axis=1)
    x[0, rng.choice(500, 60, replace=False)] = np.nan
    d, pairs = SF.structure_function_fft(x, 40)
    for row in range(2):
        for j in (1, 7, 40):
            diff = x[row, j:] - x[row, :-j]
            ok = np.isfinite(diff)
            assert pairs[row, j - 1] == ok.sum()
            assert d[row, j - 1] == pytest.approx(np.mean(diff[ok] ** 2), rel=1e-9)


def test_running_mean_matches_pandas_centred_rolling():
    rng = np.random.default_rng(2)
    x = rng.standard_normal(300)
    out = SF.remove_running_mean(x[None, :], 21)[0]
    ref = x - pd.Series(x).rolling(21, center=True, min_periods=1).mean().to_numpy()
    np.testing.assert_allclose(out, ref, atol=1e-12)


def test_rotation_puts_mean_wind_on_the_longitudinal_axis():
    rng = np.random.default_rng(3)
    n = 1000
    u = 3.0 + 0.5 * rng.standard_normal(n)
    v = -4.0 + 0.5 * rng.standard_normal(n)
    grid = np.stack([u, v, rng.standard_normal(n)])[None]
    rot, speed = S.rotate_to_mean_wind(grid)
    assert speed[0] == pytest.approx(np.hypot(u.mean(), v.mean()), rel=1e-12)
    assert rot[0, 0].mean() == pytest.approx(speed[0], rel=1e-12)
    assert abs(rot[0, 1].mean()) < 1e-12
    np.testing.assert_allclose(rot[0, 0] ** 2 + rot[0, 1] ** 2, u**2 + v**2, rtol=1e-12)


def _lags(r_min: float = 0.5, k: int = 200) -> np.ndarray:
    return (r_min * np.arange(1, k + 1))[None, :]


def test_noise_free_power_law_is_type_1_with_its_slope():
    r = _lags()
    y = 0.6 * np.log10(r)
    dec = sonic_fits.decide_types(
        r, y, r_norm=1.0, kd_threshold=0.9985, precedence_tolerance=0.05, min_points=5
    )
    assert dec.sf_type[0] == 1
    assert dec.line.coef[0, 1] == pytest.approx(0.6, abs=1e-9)
    assert dec.r_max[0] == pytest.approx(r[0, -1])


def test_noise_free_parabola_is_type_2_with_its_coefficients():
    r = _lags()
    x = np.log10(r)
    y = 0.8 * x - 0.25 * x**2
    dec = sonic_fits.decide_types(
        r, y, r_norm=1.0, kd_threshold=0.9985, precedence_tolerance=0.05, min_points=5
    )
    assert dec.sf_type[0] == 2
    np.testing.assert_allclose(dec.parabola.coef[0], [0.0, 0.8, -0.25], atol=1e-8)


def test_noise_free_parabola_then_line_is_type_3_with_break_between_r_p_and_r_l():
    r = _lags(0.3, 400)
    x = np.log10(r)
    xs = np.log10(4.0)
    y = np.where(x <= xs, 0.8 * x - 0.5 * x**2, 0.8 * xs - 0.5 * xs**2 + 0.7 * (x - xs))
    dec = sonic_fits.decide_types(
        r, y, r_norm=1.0, kd_threshold=0.9985, precedence_tolerance=0.05, min_points=5
    )
    assert dec.sf_type[0] == 3
    assert dec.r_p[0] <= 4.0 * 1.3 and dec.r_l[0] >= dec.r_p[0]
    assert 0.5 * (dec.r_p[0] + dec.r_l[0]) == pytest.approx(4.0, rel=0.3)
    assert dec.tail.coef[0, 1] == pytest.approx(0.7, abs=0.01)
    np.testing.assert_allclose(dec.parabola.coef[0, 1:], [0.8, -0.5], atol=0.05)


def test_fit_range_below_r_n_is_rejected():
    # r_max would stay below 1 m: the line breaks to a flat tail at 0.8 m
    r = _lags(0.05, 200)
    x = np.log10(r)
    y = np.where(r < 0.8, 0.66 * x, 0.66 * np.log10(0.8)) + 0.3 * np.sin(40 * x) * (r > 0.8)
    dec = sonic_fits.decide_types(
        r, y, r_norm=1.0, kd_threshold=0.9985, precedence_tolerance=0.05, min_points=5
    )
    assert dec.sf_type[0] == 0


# ----------------------------------------------------------------------------- simulated types


@pytest.mark.parametrize("sf_type", [1, 2, 3])
def test_simulated_types_are_recognised_in_95_percent_of_windows(sims, sf_type):
    _, sf = sims[sf_type]
    share = float((sf["sf_type"] == sf_type).mean())
    assert share >= 0.95, f"type {sf_type} recognised in {share:.0%} of windows"


def test_kolmogorov_series_gives_slope_two_thirds(sims):
    _, sf = sims[1]
    mu = sf["sf_mu"].values[np.isfinite(sf["sf_mu"].values)]
    assert mu.size >= 60
    # window-to-window scatter ~0.03 (sampling), mean of ~70 windows within 0.02 of 2/3
    assert np.mean(mu) == pytest.approx(2.0 / 3.0, abs=0.02)
    assert np.all(np.abs(mu - 2.0 / 3.0) < 0.12)
    # the prescribed power law ends (flat) at r_out = 20 m: r_max within 20 m .. 35 m
    r_max = sf["r_max"].values[sf["sf_type"].values == 1]
    assert 15.0 < np.median(r_max) < 35.0


def test_type2_coefficients_recovered(sims):
    _, sf = sims[2]
    model = default_models(2)[0]
    a1 = sf["sf_a1"].values[np.isfinite(sf["sf_a1"].values)]
    a2 = sf["sf_a2"].values[np.isfinite(sf["sf_a2"].values)]
    assert np.mean(a1) == pytest.approx(model.a1, abs=0.03)
    assert np.mean(a2) == pytest.approx(model.a2, abs=0.03)
    assert np.percentile(np.abs(a2 - model.a2), 90) < 0.06


def test_type3_break_and_coefficients_recovered(sims):
    _, sf = sims[3]
    model = default_models(3)[0]
    t3 = sf["sf_type"].values == 3
    assert np.median(sf["r_s"].values[t3]) == pytest.approx(model.r_s_m, rel=0.25)
    assert np.median(sf["sf_gamma"].values[t3]) == pytest.approx(model.slope, abs=0.05)
    assert np.median(sf["sf_d1"].values[t3]) == pytest.approx(model.a1, abs=0.05)
    assert np.median(sf["sf_d2"].values[t3]) == pytest.approx(model.a2, abs=0.08)
    # the acceptance rules of the paper hold for every type-3 window
    r_min = np.broadcast_to(sf["r_min"].values[:, None], t3.shape)[t3]
    r_p, r_l, r_max = (sf[k].values[t3] for k in ("r_p", "r_l", "r_max"))
    assert np.all((r_l - r_p) / ((r_max - r_l) + (r_p - r_min)) < 0.25)
    assert np.all(r_p - r_min <= r_max - r_l)


def test_structure_constant_is_d_at_one_metre(sims):
    _, sf = sims[1]
    model = default_models(1)[0]
    c = sf["structure_constant"].sel(component="longitudinal").values
    # C = D(1 m) = 0.05 m2 s-2 (prescribed), within sampling scatter
    assert np.nanmedian(c) == pytest.approx(model.c_m2s2, rel=0.15)


# ----------------------------------------------------------------------------- data problems


def test_calm_and_strong_wind_windows_are_skipped():
    # near-calm air: mean wind 5 mm/s, so even the largest lag (60 s) is 0.3 m < r_N
    calm = simulate_sonic_dataset(hours=0.5, sf_type=1, seed=4)
    rng = np.random.default_rng(4)
    for name in ("u", "v", "w"):
        calm[name] = ("time", 0.004 + 0.002 * rng.standard_normal(calm.sizes["time"]))
    sf = S.structure_function_types(calm)
    assert np.all(sf["lag_distance"].values[:, -1] < 1.0)
    assert np.all(sf["window_flag"].values & S.FLAG_CALM)
    assert np.all(sf["sf_type"].values == 0)
    strong = simulate_sonic_dataset(hours=0.5, sf_type=1, seed=5, speed=14.0)
    sf = S.structure_function_types(strong)
    assert np.all(sf["r_min"].values > 1.0)
    assert np.all(sf["window_flag"].values & S.FLAG_STRONG_WIND)
    assert np.all(sf["sf_type"].values == 0)


def test_gaps_nans_and_flagged_spikes(sims):
    ds, clean = sims[2]
    ds = ds.isel(time=slice(0, 6 * 6420)).copy(deep=True)
    n = ds.sizes["time"]
    rng = np.random.default_rng(6)
    keep = np.ones(n, bool)
    keep[6420 : 6420 + 2000] = False  # window 1 loses 31 %: skipped
    keep[3 * 6420 + 100 : 3 * 6420 + 160] = False  # window 3 loses 1 %: analysed
    u = ds["u"].values.copy()
    u[rng.choice(n, n // 200, replace=False)] = np.nan  # 0.5 % NaN everywhere
    spikes = rng.choice(np.flatnonzero(keep), 30, replace=False)
    u[spikes] += 25.0
    flag = np.zeros(n, np.int8)
    flag[spikes] = 2
    ds["u"] = ("time", u)
    ds["sample_flag"] = ("time", flag)
    sf = S.structure_function_types(ds.isel(time=keep))
    assert sf.sizes["window"] == 6
    assert sf["window_flag"].values[1] == S.FLAG_FEW_SAMPLES
    assert np.all(sf["sf_type"].values[1] == 0)
    assert sf["valid_fraction"].values[3] == pytest.approx(1 - 60 / 6420 - 0.005, abs=0.004)
    others = [0, 2, 3, 4, 5]
    assert np.all(sf["sf_type"].values[others] == 2)
    # the result barely moves with 0.5 % missing samples
    np.testing.assert_allclose(sf["sf_a1"].values[others], clean["sf_a1"].values[others], atol=0.03)
    # without the flag the spikes would be used and change the result
    unflagged = S.structure_function_types(ds.drop_vars("sample_flag").isel(time=keep))
    assert not np.allclose(
        unflagged["sf_at_normalisation_lag"].values[others, 0],
        sf["sf_at_normalisation_lag"].values[others, 0],
        rtol=0.05,
    )


def test_missing_rate_is_a_clear_error():
    ds = simulate_sonic_dataset(hours=0.2, sf_type=1, seed=1)
    ds.attrs.pop("sampling_rate_hz")
    with pytest.raises(CwprocError, match="sampling_rate_hz"):
        S.structure_function_types(ds)


# ----------------------------------------------------------------------------- summaries, pipeline


def test_summary_tables_count_what_the_product_holds(sims):
    _, sf = sims[3]
    occ = tables.type_occurrence(sf)
    assert list(occ.index) == list(S.COMPONENTS)
    row = occ.loc["longitudinal"]
    assert row["all_types_pct"] == pytest.approx(
        row["type1_pct"] + row["type2_pct"] + row["type3_pct"]
    )
    n3 = int((sf["sf_type"].sel(component="longitudinal") == 3).sum())
    assert row["type3_pct"] == pytest.approx(100 * n3 / sf.sizes["window"])
    stats = tables.parameter_statistics(sf)
    g = stats.query("type == 3 and component == 'longitudinal' and parameter == 'sf_gamma'")
    assert int(g["count"].iloc[0]) == n3
    vals = sf["sf_gamma"].sel(component="longitudinal").values
    assert float(g["median"].iloc[0]) == pytest.approx(np.nanmedian(vals))


def test_pipeline_calls_the_stage_with_matching_keywords():
    ds = simulate_sonic_dataset(hours=0.5, sf_type=2, seed=3)
    out = process_sonic(ds, load_config("meteo2"))
    assert set(out) == {"sf"}
    assert out["sf"].sizes["component"] == 3


def test_custom_models_changes_outcome():
    model = SFModel(1, slope=0.5, r_out_m=20.0)
    ds = simulate_sonic_dataset(hours=1, seed=8, models=(model, model, model))
    sf = S.structure_function_types(ds)
    mu = sf["sf_mu"].values
    assert np.nanmean(mu) == pytest.approx(0.5, abs=0.03)


def test_batched_windows_give_identical_results(sims, monkeypatch):
    ds, whole = sims[3]
    monkeypatch.setattr(S, "WINDOW_BATCH", 5)
    assert len(S.window_batches(ds["time"].values, 600.0, 5)) == 5  # 24 windows
    batched = S.structure_function_types(ds)
    xr.testing.assert_identical(batched, whole)


def test_constant_or_missing_components_are_not_typed(sims):
    ds = sims[1][0].isel(time=slice(0, 3 * 6420)).copy(deep=True)
    ds["w"] = ("time", np.zeros(ds.sizes["time"]))  # no vertical fluctuation at all
    sf = S.structure_function_types(ds)
    assert np.all(sf["sf_type"].sel(component="vertical").values == 0)
    assert np.all(sf["sf_type"].sel(component="longitudinal").values == 1)
    ds["u"] = ("time", np.full(ds.sizes["time"], np.nan))  # a dead sensor path
    sf = S.structure_function_types(ds)
    assert np.all(sf["window_flag"].values == S.FLAG_FEW_SAMPLES)
    assert np.all(sf["sf_type"].values == 0)


@pytest.mark.parametrize("deg", [1, 2])
def test_grown_fit_in_blocks_equals_one_block(monkeypatch, deg):
    """Growing the fits block by block (series leave after their first failure) gives
    exactly the ends, coefficients and k_d of evaluating every end at once."""
    rng = np.random.default_rng(7)
    n_series, n_lags = 60, 400
    x = np.log10(np.arange(1, n_lags + 1) * 0.05)[None, :].repeat(n_series, axis=0)
    curve = rng.uniform(-1.0, 1.0, (n_series, 1)) * x**2 + rng.uniform(0.5, 1.0, (n_series, 1)) * x
    y = curve + rng.normal(0, rng.uniform(1e-4, 1e-3, (n_series, 1)), x.shape)
    y[rng.random(y.shape) < 0.02] = np.nan
    sums = sonic_fits.running_sums(x, y, 2)
    start = rng.integers(0, 100, n_series)
    args = {"kd_threshold": 0.999, "min_points": 5}
    blocked = sonic_fits.grow_polynomial_fit(sums, start, deg, **args)
    monkeypatch.setattr(sonic_fits, "_FIRST_BLOCK", 10 * n_lags)
    whole = sonic_fits.grow_polynomial_fit(sums, start, deg, **args)
    assert (blocked.end >= 0).sum() > n_series // 4  # many fits grow, some stop early
    assert len(set(blocked.end[blocked.end >= 0])) > 5
    np.testing.assert_array_equal(blocked.end, whole.end)
    np.testing.assert_array_equal(blocked.coef, whole.coef)
    np.testing.assert_array_equal(blocked.kd, whole.kd)


def test_structure_function_of_complete_series_equals_the_batched_transform():
    """Without missing samples one transform of the mask serves all series: D and N_j
    are exactly those of transforming every series' mask (pairs N_j = N - j)."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(7, 1000))
    d, pairs = SF.structure_function_fft(x, 64)
    nfft = next_fast_len(1000 + 65, real=True)
    fm, fa, fs = (np.fft.rfft(v, nfft, axis=-1) for v in (np.ones_like(x), x, x * x))

    def corr(p, q):
        return np.fft.irfft(np.conj(p) * q, nfft, axis=-1)[..., 1:65]

    ref_pairs = np.rint(corr(fm, fm))
    ref_d = (corr(fm, fs) + corr(fs, fm) - 2.0 * corr(fa, fa)) / ref_pairs
    np.testing.assert_array_equal(pairs, ref_pairs)
    np.testing.assert_array_equal(pairs[0], 1000 - np.arange(1, 65))
    np.testing.assert_array_equal(d, np.maximum(ref_d, 0.0))


def test_running_mean_and_grid_shortcuts_equal_the_general_paths():
    """A complete series uses the window lengths as counts, and time-ordered samples
    skip the sort of the window indices: both give exactly the general results."""
    rng = np.random.default_rng(11)
    x = rng.normal(size=(4, 500))
    gappy = x.copy()
    gappy[0, 0] = np.nan  # another row with a gap sends the call to the general path
    complete = SF.remove_running_mean(x, 61)
    general = SF.remove_running_mean(np.concatenate([x, gappy[:1]]), 61)[:4]
    np.testing.assert_array_equal(complete, general)
    t0 = np.datetime64("2024-06-01T00:00:00", "ns")
    time = t0 + (np.arange(3000) * 1e8).astype("timedelta64[ns]")  # 10 Hz, 5 min
    values = rng.normal(size=(3, 3000))
    valid = rng.random((3, 3000)) > 0.01
    order = rng.permutation(3000)
    ordered = S.grid_windows(time, values, valid, window_s=60.0, rate_hz=10.0)
    shuffled = S.grid_windows(
        time[order], values[:, order], valid[:, order], window_s=60.0, rate_hz=10.0
    )
    for a, b in zip(ordered, shuffled, strict=True):
        np.testing.assert_array_equal(a, b)
    assert ordered[1].shape == (5, 3, 600)
    # every sample valid: sample i in slot i mod 600 of window i // 600
    _, grid, counts = S.grid_windows(
        time, values, np.ones((3, 3000), bool), window_s=60.0, rate_hz=10.0
    )
    np.testing.assert_array_equal(grid, values.reshape(3, 5, 600).transpose(1, 0, 2))
    np.testing.assert_array_equal(counts, [600] * 5)
    np.testing.assert_array_equal(ordered[1][~np.isnan(ordered[1])].size, valid.sum())


def test_windows_transformed_in_any_groups_give_identical_results(sims, monkeypatch):
    """Windows detrended and transformed one by one, a few or all at once (groups that
    mix complete windows with windows missing samples) give the same product, bit for
    bit: every step works window by window."""
    ds, _ = sims[2]
    ds = ds.copy(deep=True)
    u = ds["u"].values.copy()
    u[2 * 6420 : 4 * 6420 : 97] = np.nan  # windows 2 and 3 miss 1 % of their samples
    ds["u"] = ("time", u)
    keep = np.ones(ds.sizes["time"], bool)
    keep[5 * 6420 + 300 : 5 * 6420 + 700] = False  # a gap in window 5
    ds = ds.isel(time=keep)
    products = []
    for group in (1, 3, 24):
        monkeypatch.setattr(S, "FFT_WINDOWS", group)
        products.append(S.structure_function_types(ds))
    assert (products[0]["valid_fraction"].values < 1).sum() == 3
    for other in products[1:]:
        xr.testing.assert_identical(other, products[0])
