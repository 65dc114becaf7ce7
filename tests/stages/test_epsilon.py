"""Dissipation rate from D_L (Smalikho (2020), eqs. 4-5, 15-21; Banakh et al. (1999), eq. 19)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from cwproc.physics import spectra
from cwproc.physics.probe_variance import averaging_loss, passed_variance
from cwproc.physics.removed_share import (
    circle_removed_d,
    partial_circle,
    sector_removed_d,
    sector_removed_share,
)
from cwproc.physics.structure_fit import eq5_epsilon, fit_structure_function
from cwproc.physics.transfer import PulsedProbe
from cwproc.stages.epsilon import estimate_epsilon
from cwproc.stages.epsilon.flags import (
    FLAG_BEYOND_INERTIAL,
    FLAG_FIT_FAILED,
    FLAG_METHOD1_INVALID,
    FLAG_PARTIAL_BLOCK,
    FLAG_TOO_FEW_PAIRS,
)
from cwproc.tables.atable import get_a_table
from cwproc.tables.removed_share import mean_removed_share

PHI = 35.3  # deg
DTHETA = 2.0  # deg -> lags 1..4 within 9 deg
N_LAGS = 4
# dy = 6 m at this height: the row (phi 35.3, dy 6) of REFERENCE_VALUES.md section 1.3.pi
H_DY6 = 6.0 * np.tan(np.deg2rad(PHI)) / np.deg2rad(DTHETA)
HEIGHTS = np.array([H_DY6, 140.0])
T_SCAN = 60.0  # s
PROBE = PulsedProbe(15.3, 18.0, "physical")


@pytest.fixture(scope="module")
def options(tmp_path_factory):
    """A-table options: a private cache and the heights/outer scales these tests need."""
    return {
        "cache_dir": str(tmp_path_factory.mktemp("atable")),
        "height_range_m": (100.0, 150.0),
        "outer_scale_range_m": (20.0, 600.0),
    }


def scan_speed(h):
    return 2 * np.pi * h / np.tan(np.deg2rad(PHI)) / T_SCAN  # Smalikho (2020) eq. 3


def make_sf(d, *, mu, variance=1.0, pairs=1000):
    """A structure-function dataset (stage structure schema) with given D_L and mu."""
    d = np.asarray(d, dtype=float)
    n_t, n_h, n_l = d.shape
    u = np.asarray(mu, dtype=float) * scan_speed(HEIGHTS)[None, :]
    return xr.Dataset(
        {
            "structure_function": (("time", "height", "lag"), d),
            "n_pairs": (("time", "height", "lag"), np.broadcast_to(pairs, d.shape).copy()),
            "radial_velocity_variance": (
                ("time", "height"),
                np.broadcast_to(variance, (n_t, n_h)).astype(float),
            ),
            "wind_speed": (("time", "height"), np.broadcast_to(u, (n_t, n_h)).copy()),
            "azimuth_step": ("time", np.full(n_t, DTHETA)),
            "scan_period": ("time", np.full(n_t, T_SCAN)),
            "n_scans": ("time", np.full(n_t, 10)),
        },
        coords={
            "time": np.datetime64("2024-01-01T00:00", "ns")
            + np.arange(n_t) * np.timedelta64(10, "m"),
            "height": HEIGHTS,
            "range": ("height", HEIGHTS / np.sin(np.deg2rad(PHI))),
            "lag": np.arange(1, n_l + 1),
            "elevation": ("time", np.full(n_t, PHI)),
        },
    )


def model_d(table, eps, noise, mu, outer=None):
    """D_L = eps^(2/3) A_2 + 2 sigma_e^2 (Smalikho (2020), eq. 4) on the (time, height) grid."""
    mu = np.asarray(mu, dtype=float)
    lags = np.arange(1, N_LAGS + 1)
    _, a2 = table.evaluate(
        lags[None, None, :], HEIGHTS[None, :, None], mu[..., None], outer_scale_m=outer
    )
    return eps ** (2 / 3) * a2 + 2 * noise**2


def test_eq5_and_least_squares_invert_the_model_exactly():
    a = np.array([[1.0, 2.5, 3.7, 4.6]])
    d = 0.01 ** (2 / 3) * a + 2 * 0.2**2
    assert eq5_epsilon(d[:, 2], d[:, 0], a[:, 2], a[:, 0])[0] == pytest.approx(0.01, rel=1e-12)
    eps, noise, fitted = fit_structure_function(d, a, np.ones_like(a, dtype=bool))
    assert eps[0] == pytest.approx(0.01, rel=1e-10)
    assert noise[0] == pytest.approx(0.2, rel=1e-10) and fitted[0]
    # D(l) <= D(1): eq. 5 undefined
    assert np.isnan(eq5_epsilon(np.array([0.1]), np.array([0.2]), a[:, 2], a[:, 0]))[0]
    # a negative intercept: never a measured sigma_e = 0; without a prediction the slope
    # is refitted through 0 and sigma_e is NaN
    low = 0.01 ** (2 / 3) * a - 0.05
    eps0, noise0, fitted0 = fit_structure_function(low, a, np.ones_like(a, bool))
    assert np.isnan(noise0[0]) and not fitted0[0] and eps0[0] < 0.01
    # with the predicted sigma_e the intercept is fixed at 2 sigma_pred^2
    _, _, fitted_p = fit_structure_function(
        d, a, np.ones_like(a, bool), noise_prior=np.array([0.2])
    )
    assert fitted_p[0]  # a determined intercept is kept
    two = np.array([[True, True, False, False]])  # two lags: intercept not determined
    eps_2, noise_2, fitted_2 = fit_structure_function(d, a, two, noise_prior=np.array([0.2]))
    assert not fitted_2[0] and noise_2[0] == 0.2
    assert eps_2[0] == pytest.approx(0.01, rel=1e-10)


def test_averaging_loss_is_the_filtered_variance_deficit():
    """Loss -> (1/2)[(8/3) r^(2/3) - A_perp(r)] at large r (Smalikho (2020), eqs. 16-20).

    REFERENCE_VALUES.md 1.2 with C = 0.0652 (dy = 3 m, printed Gaussian term): at r = 60 m
    the deficit is (40.8698 - 33.64765)/2 = 3.611; the limit r -> inf is a little larger.
    """
    printed = PulsedProbe(15.3, 18.0, "printed")
    loss = averaging_loss(printed, np.array([3.0]), np.array([100.0]))[0]
    c = 0.0652 / spectra.exact_plane_constant()  # the reference used the printed C
    assert 3.611 < loss * c < 3.611 * 1.08
    # more averaging (larger dy) loses more variance
    assert averaging_loss(PROBE, np.array([12.0]), np.array([100.0]))[0] > loss


@pytest.mark.parametrize("model", ["exponential", "von_karman"])
def test_passed_variance_without_probe_is_the_model_variance(model):
    """No probe (dp = dR = dy = 0): the quadrant integral of Phi_L is sigma_V^2/eps^(2/3).

    Banakh et al. (1999), eq. 19: exponential (L_V/1.331)^(2/3); von Karman its own
    constant (:func:`cwproc.physics.spectra.variance_per_eps23`); within 0.1 %.
    """
    scales = np.array([30.0, 300.0, 3000.0])
    got = passed_variance(PulsedProbe(0.0, 0.0), np.zeros(1), np.array([100.0]), model, scales)
    want = [spectra.variance_per_eps23(model, x) for x in scales]
    np.testing.assert_allclose(got[0], want, rtol=1e-3)


@pytest.mark.slow
def test_passed_variance_is_the_variance_of_the_probe_averaged_velocity():
    """The probe removes part of sigma_V^2 at scales below its size, more for longer probes.

    Against the simulator's exact same-beam variance of V_D (Banakh et al. (1999), eq. 15)
    for a cw Lorentzian with a negligible part behind the lidar (a0 = 0.3 m: 0.1 % at
    R = 400 m), exponential model, L_V = 100 m: within 1 %.
    """
    from cwproc.physics.correlation import same_beam_variance
    from cwproc.physics.cw_probe import cw_probe_quadrature
    from cwproc.physics.transfer import CWProbe

    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.3)
    ranges = np.array([100.0, 400.0])
    got = passed_variance(probe, np.zeros(2), ranges, "exponential", [100.0])[:, 0]
    total = spectra.variance_per_eps23("exponential", 100.0)
    want = [
        same_beam_variance(cw_probe_quadrature(r, 10.6e-6, 0.3, n_fine=2000), 1.0, 100.0)
        for r in ranges
    ]
    np.testing.assert_allclose(got / total, want, rtol=0.01)
    assert got[1] < got[0] < total


@pytest.mark.slow
def test_exact_model_data_give_eps_noise_and_the_eq21_ratio(options):
    # the small-angle A-functions of Smalikho (2020), eq. 15 (the reference values)
    options = {**options, "geometry": "small_angle"}
    table = get_a_table(
        PROBE,
        phi_deg=PHI,
        delta_theta_deg=DTHETA,
        n_lags=N_LAGS,
        model="inertial",
        cache_dir=options["cache_dir"],
        height_range_m=options["height_range_m"],
        geometry="small_angle",
    )
    mu = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
    d = model_d(table, 0.003, 0.15, mu)
    out = estimate_epsilon(
        make_sf(d, mu=mu), probe=PROBE, lag_number=3, model="inertial", table_options=options
    )
    np.testing.assert_allclose(out["epsilon"].values, 0.003, rtol=1e-9)
    np.testing.assert_allclose(out["epsilon_fit"].values, 0.003, rtol=1e-9)
    np.testing.assert_allclose(out["noise_std"].values, 0.15, rtol=1e-9)
    np.testing.assert_allclose(out["mu"].values, mu, rtol=1e-12)
    # eq. 21 at phi 35.3, dy 6 m, l = 3 (REFERENCE_VALUES.md 1.3.pi): 1, 1.1575, 2.4039
    a1, _ = table.evaluate(
        np.arange(1, N_LAGS + 1)[None, None, :], HEIGHTS[None, :, None], mu[..., None]
    )
    eq21 = eq5_epsilon(d[..., 2], d[..., 0], a1[..., 2], a1[..., 0]) / 0.003
    np.testing.assert_allclose(eq21[:, 0], [1.0, 1.1575, 2.4039], rtol=2e-3)
    # method 1 is the same least squares (eq. 4) with A_1: its bias grows with mu like eq. 21
    eps1, _, _ = fit_structure_function(d, a1 + 0 * d, np.ones(d.shape, bool))
    np.testing.assert_allclose(out["epsilon_method1"].values, eps1, rtol=1e-9)
    ratio = out["epsilon_ratio"].values[:, 0]
    assert ratio[0] == pytest.approx(1.0, abs=1e-9) and 1.1 < ratio[1] < ratio[2]
    np.testing.assert_allclose(out["transverse_resolution"].values[0, 0], 6.0, rtol=1e-9)
    # the sampling geometry is an auxiliary coordinate (CF), not a data variable
    for name in ("transverse_resolution", "scan_speed"):
        assert name in out.coords and name not in out.data_vars
        assert out[name].dims == ("time", "height")
    # the fitted model reproduces the exact data (Smalikho (2020), eq. 4)
    assert out["structure_function_model"].dims == ("time", "height", "lag")
    np.testing.assert_allclose(out["structure_function_model"].values, d, rtol=1e-9)
    # method 1 beyond its validity (ratio > 1.1): kept with flag 4 (its bias is the
    # observable of Smalikho (2020), eq. 21), method 2 unaffected
    flag = out["turbulence_flag"].values
    np.testing.assert_array_equal(flag[0], [0, 0])
    assert np.all(flag[1:] & FLAG_METHOD1_INVALID)
    np.testing.assert_allclose(
        out["epsilon_method1"].values, 0.003 * out["epsilon_ratio"].values, rtol=1e-9
    )
    np.testing.assert_allclose(out["edr"].values, 0.003 ** (1 / 3), rtol=1e-9)


@pytest.mark.slow
def test_blocks_with_fewer_than_half_the_scans_are_not_estimated(options):
    """12 scans in blocks of 10 leave a block of 2: flag 16, no eps; 5 of 10 are kept."""
    table = get_a_table(
        PROBE,
        phi_deg=PHI,
        delta_theta_deg=DTHETA,
        n_lags=N_LAGS,
        model="inertial",
        cache_dir=options["cache_dir"],
        height_range_m=options["height_range_m"],
    )
    mu = np.zeros((3, 2))
    sf = make_sf(model_d(table, 0.003, 0.1, mu), mu=mu)
    sf["n_scans"].values[:] = [10, 2, 5]
    sf["structure_function"].attrs["n_scans_per_block"] = 10
    out = estimate_epsilon(sf, probe=PROBE, lag_number=3, model="inertial", table_options=options)
    flag = out["turbulence_flag"].values
    np.testing.assert_array_equal(flag[[0, 2]], 0)
    assert np.all(flag[1] & FLAG_PARTIAL_BLOCK)
    for name in ("epsilon", "epsilon_fit", "integral_scale", "velocity_variance"):
        assert np.all(np.isnan(out[name].values[1])), name
        np.testing.assert_allclose(out["epsilon"].values[[0, 2]], 0.003, rtol=1e-9)


@pytest.mark.slow
def test_flags_explain_every_missing_value(options):
    table = get_a_table(
        PROBE,
        phi_deg=PHI,
        delta_theta_deg=DTHETA,
        n_lags=N_LAGS,
        model="inertial",
        cache_dir=options["cache_dir"],
        height_range_m=options["height_range_m"],
    )
    mu = np.zeros((4, 2))
    d = model_d(table, 0.003, 0.1, mu)
    pairs = np.full(d.shape, 1000)
    pairs[0, 0, :] = 50  # too few pairs
    d[1, 0] = d[1, 0, ::-1].copy()  # D decreasing with the lag: no positive slope, fit fails
    sf = make_sf(d, mu=mu, pairs=pairs)
    sf["wind_speed"][2, 0] = np.nan  # no wind for mu
    sf["radial_velocity_variance"][3, 0] = 1e-4  # tiny variance: L_V below the lags
    out = estimate_epsilon(sf, probe=PROBE, lag_number=3, model="inertial", table_options=options)
    flag = out["turbulence_flag"].values
    assert flag[0, 0] & FLAG_TOO_FEW_PAIRS
    assert flag[1, 0] & FLAG_FIT_FAILED
    assert flag[2, 0] & FLAG_FIT_FAILED
    assert flag[3, 0] & FLAG_BEYOND_INERTIAL
    assert np.all(np.isnan(out["epsilon"].values[:, 0]))
    np.testing.assert_array_equal(flag[:, 1], 0)
    np.testing.assert_allclose(out["epsilon"].values[:, 1], 0.003, rtol=1e-9)


@pytest.mark.slow
def test_finite_outer_scale_fit_recovers_eps_and_integral_scale(options):
    """Data of a von Karman field with L_V = 60 m (lags up to 24 m, probe ~48 m).

    The inertial-range A-functions bias eps low (REFERENCE_VALUES.md section 3); fitting
    eps with L_V through sigma_V^2 = (eps L_V / c)^(2/3) (Banakh et al. (1999), eq. 19)
    recovers both.
    """
    eps, noise, big_l = 0.003, 0.1, 60.0
    table = get_a_table(
        PROBE,
        phi_deg=PHI,
        delta_theta_deg=DTHETA,
        n_lags=N_LAGS,
        model="von_karman",
        **options,
    )
    mu = np.full((1, 2), 0.5)
    d = model_d(table, eps, noise, mu, outer=big_l)
    r = HEIGHTS / np.sin(np.deg2rad(PHI))
    dy = np.deg2rad(DTHETA) * HEIGHTS / np.tan(np.deg2rad(PHI))
    sigma2 = spectra.variance_from(eps, big_l, "von_karman")
    # what the block variance of V'_L shows: the probe-passed part of sigma_V^2 of the
    # von Karman field (not sigma_V^2 minus the inertial loss) plus noise
    var_raw = eps ** (2 / 3) * passed_variance(PROBE, dy, r, "von_karman", [big_l])[:, 0]
    var_raw = var_raw + noise**2
    sf = make_sf(d, mu=mu, variance=var_raw[None, :])
    vk = estimate_epsilon(sf, probe=PROBE, lag_number=3, model="von_karman", table_options=options)
    np.testing.assert_allclose(vk["epsilon"].values, eps, rtol=0.02)
    np.testing.assert_allclose(vk["integral_scale"].values, big_l, rtol=0.05)
    np.testing.assert_allclose(vk["velocity_variance"].values, sigma2, rtol=0.03)
    np.testing.assert_allclose(vk["noise_std"].values, noise, rtol=0.05)
    inertial = estimate_epsilon(
        sf, probe=PROBE, lag_number=3, model="inertial", table_options=options
    )
    assert np.all(inertial["epsilon"].values < 0.9 * eps)


# --------------------------------------------------------------------------------------
# end to end: synthetic von Karman turbulence -> pulsed conical scans -> D_L -> eps
# --------------------------------------------------------------------------------------

SIM_EPS = 0.01  # m2 s-3
SIM_L = 100.0  # m, integral scale of the synthetic field
SIM_NOISE = 0.3  # m s-1
SIM_PHI = 35.3
SIM_HEIGHTS = np.array([80.0, 100.0, 120.0])
SIM_RAYS = 144  # dtheta 2.5 deg -> lags 1..3; dy = 6.2 m at 100 m
SIM_T = 120.0
SIM_OPTIONS = {"height_range_m": (75.0, 125.0), "outer_scale_range_m": (20.0, 600.0)}


def vad_wind(ds: xr.Dataset) -> xr.Dataset:
    """Per-scan least-squares VAD winds (Smalikho (2020), eq. 1) in the stage-vad schema."""
    scans = np.unique(ds["scan"].values)
    th = np.deg2rad(ds["azimuth"].values)
    ph = np.deg2rad(ds["elevation"].values)
    design = np.stack([np.cos(ph) * np.sin(th), np.cos(ph) * np.cos(th), np.sin(ph)], axis=1)
    coef = np.stack(
        [
            np.linalg.lstsq(
                design[ds["scan"].values == s],
                ds["radial_velocity"].values[ds["scan"].values == s],
                rcond=None,
            )[0]
            for s in scans
        ]
    )  # (scan, 3, height)
    times = np.array(
        [ds["time"].values[ds["scan"].values == s].astype("int64").mean() for s in scans]
    ).astype("datetime64[ns]")
    r = ds["range"].values
    return xr.Dataset(
        {name: (("time", "height"), coef[:, i, :]) for i, name in enumerate("uvw")},
        coords={
            "time": times,
            "height": r * np.sin(np.deg2rad(SIM_PHI)),
            "range": ("height", r),
            "scan": ("time", scans),
            "elevation": ("time", np.full(scans.size, SIM_PHI)),
        },
    )


def simulate(field, mu: float, seed: int, keep=None) -> xr.Dataset:
    """Screened scans (qc flag 0) of the field with wind speed mu V_s at 100 m."""
    from cwproc.sim.pulsed import sample_conical_scans

    v_s = 2 * np.pi * 100.0 / np.tan(np.deg2rad(SIM_PHI)) / SIM_T
    ds = sample_conical_scans(
        field,
        elevation_deg=SIM_PHI,
        ranges_m=SIM_HEIGHTS / np.sin(np.deg2rad(SIM_PHI)),
        rays_per_scan=SIM_RAYS,
        scan_period_s=SIM_T,
        n_scans=10,
        wind_speed_m_s=mu * v_s,
        wind_direction_deg=250.0,
        noise_std_m_s=SIM_NOISE,
        seed=seed,
        sweep_points=3,
        range_step_m=3.0,
    )
    if keep is not None:
        ds = ds.isel(ray=keep(ds))
    ds["qc_flag_radial"] = (("ray", "range"), np.zeros(ds["radial_velocity"].shape, np.int8))
    return ds


@pytest.fixture(scope="module")
def sim_results(tmp_path_factory):
    """eps, eps_1 (from the data with A_1), sigma_e over 4 seeded fields x 3 heights x mu."""
    from cwproc.sim.field3d import von_karman_field
    from cwproc.stages.structure import azimuth_structure_function

    options = {**SIM_OPTIONS, "cache_dir": str(tmp_path_factory.mktemp("atable_sim"))}
    out = {}
    for seed in range(4):
        field = von_karman_field(
            (128, 128, 128),
            2.0,
            epsilon=SIM_EPS,
            integral_scale_m=SIM_L,
            seed=seed,
            coarse_factor=8,
        )
        for mu in (0.0, 1.0, 2.0, 3.0):
            ds = simulate(field, mu, seed + 100)
            sf = azimuth_structure_function(ds, vad_wind(ds), n_scans=10, max_lag_deg=9.0)
            turb = estimate_epsilon(
                sf, probe=PROBE, lag_number=3, model="von_karman", table_options=options
            )
            inertial = estimate_epsilon(
                sf, probe=PROBE, lag_number=3, model="inertial", table_options=options
            )
            # method 1 straight from the data (the product masks it beyond eq. 21's 10 %)
            eps1 = inertial["epsilon"].values * inertial["epsilon_ratio"].values
            out.setdefault(mu, []).append(
                np.stack(
                    [
                        turb["epsilon"].values[0] / SIM_EPS,
                        turb["noise_std"].values[0] / SIM_NOISE,
                        inertial["epsilon"].values[0] / SIM_EPS,
                        eps1[0] / SIM_EPS,
                    ]
                )
            )
        if seed < 2:  # damaged blocks at mu = 1
            for name, keep in DAMAGE.items():
                ds = simulate(field, 1.0, seed + 100, keep)
                sf = azimuth_structure_function(ds, vad_wind(ds), n_scans=10, max_lag_deg=9.0)
                turb = estimate_epsilon(
                    sf, probe=PROBE, lag_number=3, model="von_karman", table_options=options
                )
                out.setdefault(name, []).append(
                    np.stack(
                        [
                            turb["epsilon"].values[0] / SIM_EPS,
                            turb["n_pairs"].values[0, :, 0],
                            turb["turbulence_flag"].values[0],
                        ]
                    )
                )
    return {key: np.concatenate(v, axis=1) for key, v in out.items()}


#: ray selections that damage a block: random gaps, a blind sector, almost nothing left
DAMAGE = {
    "missing": lambda ds: np.random.default_rng(5).random(ds.sizes["ray"]) > 0.2,
    "sector": lambda ds: ~((ds["azimuth"].values >= 100) & (ds["azimuth"].values < 160)),
    "too_few": lambda ds: ds["azimuth"].values < 20,
}
FULL_PAIRS = 10 * (SIM_RAYS - 1)


@pytest.mark.slow
@pytest.mark.parametrize("mu", [0.0, 1.0, 2.0, 3.0])
def test_method2_recovers_eps_of_synthetic_scans(sim_results, mu):
    """Median eps (method 2, von Karman fit) within 20 % of the truth, 12 realisations.

    At mu = 0 the ten scans of a frozen field sample one circle of air, so the scatter is
    largest there.
    """
    assert np.nanmedian(sim_results[mu][0]) == pytest.approx(1.0, abs=0.2)


@pytest.mark.slow
@pytest.mark.parametrize("mu", [0.0, 1.0, 2.0])
def test_noise_std_is_recovered(sim_results, mu):
    assert np.nanmedian(sim_results[mu][1]) == pytest.approx(1.0, abs=0.2)


@pytest.mark.slow
def test_method1_is_biased_high_beyond_mu_1(sim_results):
    """eps_1 / eps_2 grows with mu as Smalikho (2020), eq. 21 predicts (about 1.2, 2.5, 4)."""
    bias = {mu: np.nanmedian(sim_results[mu][3] / sim_results[mu][2]) for mu in (0, 1, 2, 3)}
    assert bias[0.0] == pytest.approx(1.0, abs=0.02)
    assert 1.05 < bias[1.0] < bias[2.0] < bias[3.0]
    assert bias[3.0] > 3.0
    assert np.nanmedian(sim_results[3.0][3]) > 2.0  # method 1 against the truth


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["missing", "sector"])
def test_blocks_with_gaps_still_give_eps_from_fewer_pairs(sim_results, damage):
    eps, pairs, flag = sim_results[damage]
    flag = flag.astype(int)
    assert np.all(pairs < FULL_PAIRS) and np.all(pairs > 0.5 * FULL_PAIRS)
    assert np.all(np.isfinite(eps))
    assert np.all((flag & (FLAG_TOO_FEW_PAIRS | FLAG_FIT_FAILED | FLAG_BEYOND_INERTIAL)) == 0)
    assert np.median(eps) == pytest.approx(1.0, abs=0.25)


@pytest.mark.slow
def test_blocks_with_too_few_pairs_are_flagged_not_estimated(sim_results):
    eps, pairs, flag = sim_results["too_few"]
    flag = flag.astype(int)
    assert np.all(pairs < 100)  # 8 rays of 144 left per scan
    assert np.all(np.isnan(eps))
    assert np.all(flag & FLAG_TOO_FEW_PAIRS)


def test_table_height_range_covers_the_data_in_few_distinct_steps():
    """Default 10-3000 m; a gate at 8.7 m (sample data) or 5 km widens it by 1.2^4 steps."""
    from cwproc.physics.atable import HEIGHT_RATIO
    from cwproc.stages.epsilon.atable_fit import table_height_range

    assert table_height_range(np.array([50.0, 2500.0])) == (10.0, 3000.0)
    step = HEIGHT_RATIO**4
    lo, hi = table_height_range(np.array([8.7, 100.0, 5000.0, np.nan]))
    assert lo == pytest.approx(10.0 / step) and lo < 8.7
    assert hi == pytest.approx(3000.0 * step) and hi > 5000.0
    # heights below 1 m (e.g. 0 for a ground gate) are not tabulated: flag 8 stays
    assert table_height_range(np.array([0.0, 0.5, 20.0])) == (10.0, 3000.0)
    # the same range for nearby data: one cache file
    assert table_height_range(np.array([9.5])) == table_height_range(np.array([6.0]))


def _two_beam_sf(mids_deg, *, dtheta, phi, height, eps, noise, speed, wind_to, t_ray):
    """A block's D_L from the exact two-beam model for the pairs centred on ``mids_deg``.

    Step-stare rays (no sweep), clockwise scan, Stream Line probe; ``wind_to`` the
    direction the wind blows towards (deg). ``mids_deg``: one array for every lag, or a
    list of one array per lag (the pairs of each lag), whose weights are then per lag.
    Returns the structure-function dataset.
    """
    import math

    from cwproc.physics import two_beam
    from cwproc.physics.atable_interp import azimuth_bin_weights

    rng = height / math.sin(math.radians(phi))
    a = math.radians(wind_to)
    wind = speed * np.array([0.0, math.cos(a), math.sin(a)])
    q = two_beam.beam_quadrature(PROBE, rng)
    lags = np.arange(1, 4)
    per_lag = isinstance(mids_deg, list)
    mids = mids_deg if per_lag else [mids_deg] * lags.size
    d = np.array(
        [
            np.mean(
                two_beam.two_beam_structure_function(
                    mids[lag - 1] - 0.5 * lag * dtheta,
                    mids[lag - 1] + 0.5 * lag * dtheta,
                    phi,
                    rng,
                    quadrature=q,
                    time_separation_s=-lag * t_ray,
                    mean_wind=wind,
                    epsilon=eps,
                )
            )
            for lag in lags
        ]
    )
    d = d + 2 * noise**2
    weights = np.stack([azimuth_bin_weights(np.radians(wind_to - m)) for m in mids])
    dims = ("time", "height", "lag", "azimuth_node")
    if not per_lag:
        weights, dims = weights[0], ("time", "height", "azimuth_node")
    n_rays = round(360 / dtheta)
    return xr.Dataset(
        {
            "structure_function": (("time", "height", "lag"), d[None, None, :]),
            "n_pairs": (("time", "height", "lag"), np.full((1, 1, 3), 1000)),
            "radial_velocity_variance": (("time", "height"), [[4.0]]),
            "wind_speed": (("time", "height"), [[speed]]),
            "wind_to_direction": (("time", "height"), [[wind_to]]),
            "pair_azimuth_weights": (dims, weights[None, None]),
            "azimuth_step": ("time", [dtheta]),
            "scan_period": ("time", [n_rays * t_ray]),
            "n_scans": ("time", [10]),
        },
        coords={
            "time": [np.datetime64("2024-01-01T00:00", "ns")],
            "height": [height],
            "range": ("height", [rng]),
            "lag": lags,
            "elevation": ("time", [phi]),
        },
        attrs={"swept_rays": 0},
    )


@pytest.mark.parametrize("speed", [3.0, 15.0, 40.0])
@pytest.mark.parametrize(
    ("label", "mids"),
    [
        ("full circle", np.arange(7.5, 360.0, 15.0)),
        ("60 deg gap", np.arange(67.5, 360.0, 15.0)),
        ("90 deg sector", np.arange(7.5, 90.0, 15.0)),
    ],
)
def test_step_stare_24_rays_sector_and_gap_give_epsilon(tmp_path, label, mids, speed):
    """24-ray step-stare VAD (15 deg, 3 s per ray), mu 0.2-2.6, known wind: eps within 2 %.

    D_L from the exact two-beam model of the pairs present; the full-circle A_2 would
    miss eps by up to +7 % with the 60 deg gap and -18 % in the 90 deg sector.
    """
    sf = _two_beam_sf(
        mids,
        dtheta=15.0,
        phi=60.0,
        height=300.0,
        eps=0.01,
        noise=0.1,
        speed=speed,
        wind_to=70.0,
        t_ray=3.0,
    )
    options = {"cache_dir": str(tmp_path), "height_range_m": (150.0, 600.0)}
    out = estimate_epsilon(sf, probe=PROBE, lag_number=3, model="inertial", table_options=options)
    assert float(out["epsilon"].values[0, 0]) == pytest.approx(0.01, rel=0.02), label
    assert float(out["edr"].values[0, 0]) ** 3 == pytest.approx(float(out["epsilon"].values[0, 0]))
    if label != "full circle" and speed > 10:
        circle = estimate_epsilon(
            sf.drop_vars("pair_azimuth_weights"),
            probe=PROBE,
            lag_number=3,
            model="inertial",
            table_options=options,
        )
        assert abs(float(circle["epsilon"].values[0, 0]) / 0.01 - 1) > 0.04


@pytest.mark.parametrize("wind_to", [70.0, 250.0])
def test_full_circle_pairs_that_do_not_wrap_are_weighted_per_lag(tmp_path, wind_to):
    """24-ray step-stare VAD whose pairs do not wrap from the last ray to the first.

    Lag ``l`` lacks ``l`` pair positions, always at the scan's start; at ``mu`` 1 (15
    m/s) the wind makes D vary strongly with azimuth, so the mean over the pairs present
    is not the circle mean. With the weights of each lag's pairs eps is within 1 %
    (measured 0.999-1.001 for winds towards 0-340 deg at 10 and 15 m/s); the lag-1
    weights for every lag give 0.89 (250 deg) and 1.07 (70 deg), the circle mean 0.87
    and 1.12.
    """
    mids = [7.5 * lag + 15.0 * np.arange(24 - lag) for lag in (1, 2, 3)]
    common = dict(dtheta=15.0, phi=60.0, height=300.0, eps=0.01, noise=0.1, t_ray=3.0)
    sf = _two_beam_sf(mids, speed=15.0, wind_to=wind_to, **common)
    options = {"cache_dir": str(tmp_path), "height_range_m": (150.0, 600.0)}
    kwargs = dict(probe=PROBE, lag_number=3, model="inertial", table_options=options)
    out = estimate_epsilon(sf, **kwargs)
    assert float(out["epsilon"].values[0, 0]) == pytest.approx(0.01, rel=0.01)
    lag1 = sf.assign(pair_azimuth_weights=sf["pair_azimuth_weights"].isel(lag=0, drop=True))
    old = estimate_epsilon(lag1, **kwargs)
    assert abs(float(old["epsilon"].values[0, 0]) / 0.01 - 1) > 0.05


@pytest.mark.slow
@pytest.mark.parametrize(("n_rays", "t_ray", "swept"), [(24, 3.0, False), (72, 0.5, True)])
def test_von_karman_coarse_scans_recover_eps_and_outer_scale(tmp_path, n_rays, t_ray, swept):
    """Exact two-beam von Karman data (L_V = 300 m, eps 5e-3, sigma_e 0.05, U = 10 m/s).

    24-ray step-stare VAD and 72-ray continuous scan (each ray swept over 5 deg and seen
    at its own times): eps within 2 %, L_V within 3 %, sigma_e within 15 %. The pairs
    are taken at 12 azimuths 30 deg apart, weighted as the structure stage weights its
    pairs: the 72-ray case gives eps, L_V, sigma_e 1.000893, 0.994525, 1.05236 of the
    truth, as with 36 azimuths 10 deg apart (1.000893, 0.994524, 1.05234) at a third of
    the cost (the exact swept pairs take most of it).
    """
    import math

    from cwproc.physics import two_beam
    from cwproc.physics.atable_interp import azimuth_bin_weights

    phi, h, eps, big_l, noise, speed = 60.0, 300.0, 5e-3, 300.0, 0.05, 10.0
    dtheta = 360.0 / n_rays
    rng = h / math.sin(math.radians(phi))
    q = two_beam.beam_quadrature(PROBE, rng)
    a = math.radians(70.0)
    wind = speed * np.array([0.0, math.cos(a), math.sin(a)])
    sweep = {"sweep_deg": dtheta, "n_sweep": 8} if swept else {}
    mids = np.arange(0.0, 360.0, 30.0)
    vk = {"model": "von_karman", "epsilon": eps, "outer_scale_m": big_l, "quadrature": q}
    d = np.array(
        [
            np.mean(
                two_beam.two_beam_structure_function(
                    mids - 0.5 * lag * dtheta,
                    mids + 0.5 * lag * dtheta,
                    phi,
                    rng,
                    time_separation_s=-lag * t_ray,
                    mean_wind=wind,
                    ray_duration_s=t_ray if swept else 0.0,
                    **sweep,
                    **vk,
                )
            )
            for lag in (1, 2, 3)
        ]
    )
    b0 = float(two_beam.two_beam_covariance(0.0, 0.0, phi, rng, **sweep, **vk))
    # the block-mean VAD wind of 10 back-to-back scans also takes part of D(l) (up to 60
    # rays per scan, as the stage models it: circle_removed_d)
    radius = h / math.tan(math.radians(phi))
    d = (
        d
        - spectra.variance_from(eps, big_l, "von_karman")
        * circle_removed_d(
            np.radians([dtheta]),
            3,
            np.array([[radius / big_l]]),
            np.array([speed * n_rays * t_ray / (2 * math.pi * radius)]),
            np.ones(1),
            np.array([10.0]),
            phi,
            "von_karman",
        )[0, 0]
    )
    # the block mean of 10 independent scans removes share / 10 of sigma_V^2
    share = mean_removed_share(np.array([radius / big_l]), phi, "von_karman")
    b0 = b0 - float(share[0]) * spectra.variance_from(eps, big_l, "von_karman") / 10
    sf = xr.Dataset(
        {
            "structure_function": (("time", "height", "lag"), (d + 2 * noise**2)[None, None]),
            "n_pairs": (("time", "height", "lag"), np.full((1, 1, 3), 1000)),
            "radial_velocity_variance": (("time", "height"), [[b0 + noise**2]]),
            "wind_speed": (("time", "height"), [[speed]]),
            "pair_azimuth_weights": (
                ("time", "height", "azimuth_node"),
                azimuth_bin_weights(np.radians(70.0 - mids))[None, None],
            ),
            "azimuth_step": ("time", [dtheta]),
            "scan_period": ("time", [n_rays * t_ray]),
            "n_scans": ("time", [10]),
        },
        coords={
            "time": [np.datetime64("2024-01-01T00:00", "ns")],
            "height": [h],
            "range": ("height", [rng]),
            "lag": [1, 2, 3],
            "elevation": ("time", [phi]),
        },
        attrs={"swept_rays": int(swept)},
    )
    out = estimate_epsilon(
        sf,
        probe=PROBE,
        lag_number=3,
        model="von_karman",
        table_options={"cache_dir": str(tmp_path), "height_range_m": (150.0, 600.0)},
    )
    assert float(out["epsilon"].values[0, 0]) == pytest.approx(eps, rel=0.02)
    assert float(out["integral_scale"].values[0, 0]) == pytest.approx(big_l, rel=0.03)
    fitted = np.isfinite(out["noise_std"].values[0, 0])
    assert not fitted or float(out["noise_std"].values[0, 0]) == pytest.approx(noise, rel=0.15)


def _with_covariance(sf: xr.Dataset, cov: np.ndarray) -> xr.Dataset:
    """``sf`` with the per-block covariance of ``(D_L(1..L), variance)`` of every cell."""
    shape = (sf.sizes["time"], sf.sizes["height"], *cov.shape)
    return sf.assign(
        statistics_covariance=(
            ("time", "height", "statistic", "statistic_b"),
            np.broadcast_to(cov, shape).copy(),
        )
    )


def test_standard_errors_are_the_propagated_scan_scatter(tmp_path):
    """Delta method (:func:`delta_method_errors`) against the analytic propagation.

    Inertial model, exact data of eq. 4 with a determined intercept: eps = slope^(3/2)
    of the least squares, so ``d eps / d D(l) = 1.5 slope^(1/2) (A_l - mean A) / S_AA``;
    the variance of V'_L does not enter eps, and enters sigma_V^2 one to one and L_V =
    c sigma_V^3 / eps as ``1.5 L_V / sigma_V^2``.
    """
    options = {"cache_dir": str(tmp_path), "height_range_m": (50.0, 200.0), "swept": False}
    table = get_a_table(
        PROBE, phi_deg=PHI, delta_theta_deg=DTHETA, n_lags=N_LAGS, model="inertial", **options
    )
    mu = np.full((1, 2), 0.5)
    d = model_d(table, 0.003, 0.15, mu)
    sd = 1e-3 * d[0, 0]
    corr = 0.5 ** np.abs(np.subtract.outer(np.arange(N_LAGS), np.arange(N_LAGS)))
    cov_d = np.zeros((N_LAGS + 1, N_LAGS + 1))
    cov_d[:N_LAGS, :N_LAGS] = np.outer(sd, sd) * corr
    run = {"probe": PROBE, "lag_number": 3, "model": "inertial", "table_options": options}
    out = estimate_epsilon(_with_covariance(make_sf(d, mu=mu), cov_d), **run)
    _, a2 = table.evaluate(
        np.arange(1, N_LAGS + 1)[None, None, :], HEIGHTS[None, :, None], mu[..., None]
    )
    x = a2[0] - a2[0].mean(axis=-1, keepdims=True)
    grad = 1.5 * 0.003 ** (1 / 3) * x / np.sum(x * x, axis=-1, keepdims=True)
    expected = np.sqrt(np.einsum("hi,ij,hj->h", grad, cov_d[:N_LAGS, :N_LAGS], grad))
    np.testing.assert_allclose(out["epsilon_standard_error"].values[0], expected, rtol=0.01)
    # an error of the variance alone
    cov_v = np.zeros((N_LAGS + 1, N_LAGS + 1))
    cov_v[N_LAGS, N_LAGS] = 0.02**2
    out_v = estimate_epsilon(_with_covariance(make_sf(d, mu=mu), cov_v), **run)
    assert np.all(out_v["epsilon_standard_error"].values < 1e-6 * 0.003)
    np.testing.assert_allclose(out_v["velocity_variance_standard_error"].values, 0.02, rtol=1e-6)
    np.testing.assert_allclose(
        out_v["integral_scale_standard_error"].values,
        1.5 * out_v["integral_scale"].values * 0.02 / out_v["velocity_variance"].values,
        rtol=0.01,  # a central secant over one standard error of the variance
    )


def test_sample_data_never_store_a_measured_noise_of_zero(tmp_path):
    """The README's main job: ``noise_std`` is never 0; flag 32 marks the predicted noise.

    Where the intercept of eq. 4 is not determined (flag 32) ``noise_std`` is the
    prediction ``noise_std_predicted`` (Pearson et al. (2009), eq. 3); elsewhere it is
    the fitted one. The sample's true sigma_e is 0.1 m s-1 (sample_data/README.md).
    """
    from pathlib import Path

    from click.testing import CliRunner

    from cwproc.cli import main
    from cwproc.stages.epsilon.flags import FLAG_NOISE_PREDICTED

    sample = Path(__file__).parents[2] / "sample_data"
    res = CliRunner().invoke(
        main, ["retrieve", str(sample), "-c", str(sample / "site.toml"), "-o", str(tmp_path)]
    )
    assert res.exit_code == 0, res.output
    (path,) = tmp_path.glob("*_turbulence.nc")
    with xr.open_dataset(path) as turb:
        noise = turb["noise_std"].values
        predicted = turb["noise_std_predicted"].values
        flag = turb["turbulence_flag"].values
    assert np.all(np.isfinite(noise)) and np.all(noise > 0)
    marked = (flag & FLAG_NOISE_PREDICTED) > 0
    assert marked.any() and (~marked).any()
    np.testing.assert_allclose(noise[marked], predicted[marked], rtol=1e-6)
    # the fitted ones scatter block by block about the truth
    assert np.median(noise[~marked]) == pytest.approx(0.1, rel=0.3)


def _exact_statistics_run(pattern, mu: float, n_scans: int, n_blocks: int, seed: int):
    """eps_hat/eps, reported SE and sigma_V^2 of the user's chain on exact Gaussian blocks.

    :func:`cwproc.sim.exact_gaussian.gaussian_scans` (exact covariance of the
    probe-averaged radial velocities of a von Karman field, transport included): eps
    0.01 m2 s-3, L_V 200 m, sigma_e 0.05 m s-1 with the SNR at which Pearson et al.
    (2009), eq. 3 predicts it, h 100 m, phi 35 deg; ``pipeline.process_scans`` with the
    ``streamline`` preset.
    """
    import dataclasses
    import warnings

    from scipy import optimize

    from cwproc.config import load_config
    from cwproc.physics import noise
    from cwproc.pipeline import process_scans
    from cwproc.sim import exact_gaussian as eg

    radius = 100.0 / np.tan(np.deg2rad(35.0))
    rate = (pattern.sweep_deg or 360.0 / pattern.n_rays) / pattern.dwell_s
    scans = eg.gaussian_scans(
        pattern=pattern,
        n_scans=n_scans,
        n_blocks=n_blocks,
        elevation_deg=35.0,
        ranges_m=[100.0 / np.sin(np.deg2rad(35.0))],
        epsilon=0.01,
        outer_scale_m=200.0,
        wind_speed_m_s=mu * np.deg2rad(rate) * radius,
        wind_direction_deg=250.0,
        noise_std_m_s=0.05,
        seed=seed,
    )
    attrs = scans.attrs
    band = noise.bandwidth_from_resolution(attrs["velocity_resolution_m_s"])

    def excess(log_snr: float) -> float:
        snr = 10.0**log_snr
        pred = noise.velocity_noise_std(
            snr, attrs["points_per_gate"], attrs["pulses_per_ray"], band
        )
        return float(pred) - 0.05

    scans["snr"][:] = 10.0 ** optimize.brentq(excess, -4.0, 2.0)
    base = load_config("streamline")
    config = dataclasses.replace(
        base, turbulence=dataclasses.replace(base.turbulence, n_scans=n_scans)
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        turb = process_scans(scans, config, [])["turbulence"]
    ratio = turb["epsilon"].values[:, 0] / 0.01
    se = turb["epsilon_standard_error"].values[:, 0] / 0.01
    truth_var = float(spectra.variance_from(0.01, 200.0, "von_karman"))
    return ratio, se, turb["velocity_variance"].values[:, 0] / truth_var


@pytest.mark.slow
@pytest.mark.parametrize(
    ("rays", "continuous", "period", "mu", "n_scans", "n_blocks"),
    [(24, False, 48.0, 1.0, 10, 200), (72, True, 36.0, 0.5, 5, 150)],
    ids=["24-ray step-stare VAD", "72-ray continuous"],
)
def test_exact_statistics_eps_is_unbiased_and_its_error_bar_calibrated(
    rays, continuous, period, mu, n_scans, n_blocks
):
    """Mean eps_hat/eps within 5 % plus two standard errors of the mean; se/sd in 0.8-1.2.

    Measured (docs/physics-epsilon.md, 10 scans per block): 24-ray VAD mu 1: 0.962 +-
    0.015, se/sd 0.93 (400 blocks); 72-ray continuous mu 0.5: 0.969 +- 0.011, se/sd
    1.19; here the 72-ray case runs with 5 scans per block to keep the generator fast.
    A 180-ray block covariance takes minutes to build, so that case is measured by
    ``benchmarks/bench_epsilon_accuracy.py`` only.
    """
    from cwproc.sim import exact_gaussian as eg

    pattern = eg.conical_pattern(rays, period, continuous=continuous)
    ratio, se, var = _exact_statistics_run(pattern, mu, n_scans, n_blocks, seed=11)
    assert np.all(np.isfinite(ratio))  # no block is dropped on its own fitted L_V
    sem = ratio.std(ddof=1) / np.sqrt(ratio.size)
    assert abs(ratio.mean() - 1.0) < 0.05 + 2 * sem
    assert 0.8 < np.mean(se) / ratio.std(ddof=1) < 1.2
    assert abs(np.nanmean(var) - 1.0) < 0.05


def _pair_node_weights(azimuth_deg: np.ndarray, wind_to_deg: float) -> np.ndarray:
    """Node weights of the lag-1 pairs of one scan, as the structure stage records them."""
    from cwproc.physics.atable_interp import azimuth_bin_weights

    az = np.asarray(azimuth_deg, float)
    step = np.diff(az)
    regular = step < 1.5 * np.median(step)  # pairs across a gap are not lag-1 pairs
    mids = (az[:-1] + step / 2)[regular]
    return azimuth_bin_weights(np.radians(wind_to_deg - mids))[None]


def test_partial_circle_tells_sectors_and_gaps_from_regular_scans():
    cases = {
        "24-ray VAD": (np.arange(7.5, 360.0, 15.0), 15.0, False),
        "12-ray VAD": (np.arange(15.0, 360.0, 30.0), 30.0, False),
        "180-ray scan": (np.arange(1.0, 360.0, 2.0), 2.0, False),
        "60 deg gap": (np.arange(61.0, 360.0, 2.0), 2.0, True),
        "90 deg sector": (np.arange(1.0, 90.0, 2.0), 2.0, True),
    }
    for label, (az, step, expected) in cases.items():
        w = _pair_node_weights(az, 250.0)
        assert bool(partial_circle(w, np.array([step]))[0]) is expected, label


def _exact_sector_block() -> dict:
    """Exact covariance of a block of a 90 deg step-stare sector and its VAD removal.

    15 rays of 1 s over 90 deg, 2 s back, 4 scans per block, mu = 1 (T_scan of a full
    circle at the sector's rate: 60 s), h = 100 m, phi = 35 deg, von Karman L_V = 200 m,
    eps = 0.01 (:func:`cwproc.sim.exact_gaussian.block_covariance`); ``keep`` is ``I`` less
    the block-mean VAD fit (the mean of the scans' least-squares winds).
    """
    from cwproc.physics.geometry import wind_components
    from cwproc.sim import exact_gaussian as eg

    phi, height, scale, n_scans, mu = 35.0, 100.0, 200.0, 4, 1.0
    radius = height / np.tan(np.radians(phi))
    pattern = eg.conical_pattern(15, 15.0, sector_deg=90.0, continuous=False, return_s=2.0)
    t_scan = 15.0 * 4  # a full circle at the sector's rate (s)
    u, v = wind_components(mu * 2 * np.pi * radius / t_scan, 250.0)
    cov = eg.block_covariance(
        pattern,
        n_scans,
        elevation_deg=phi,
        range_m=height / np.sin(np.radians(phi)),
        epsilon=0.01,
        outer_scale_m=scale,
        mean_wind=(u, v, 0.0),
    )
    az = np.radians(np.asarray(pattern.azimuth_deg))
    design = np.stack([np.ones(az.size), np.cos(az), np.sin(az)], -1)
    hat = design @ np.linalg.solve(design.T @ design, design.T)
    keep = np.eye(n_scans * az.size) - np.kron(np.full((n_scans, n_scans), 1 / n_scans), hat)
    return {
        "cov": cov,
        "keep": keep,
        "sigma2": spectra.variance_from(0.01, scale, "von_karman"),
        "pattern": pattern,
        "radius": radius,
        "scale": scale,
        "mu": mu,
        "phi": phi,
        "n_scans": n_scans,
        "t_scan": t_scan,
    }


def test_sector_vad_removal_matches_exact_block_statistics():
    """The share of sigma_V^2 the block-mean VAD wind takes from V'_L, against the exact
    covariance of the rays of a block (:func:`cwproc.sim.exact_gaussian.block_covariance`).

    A 90 deg step-stare sector (15 rays, 1 s each, 2 s back), 4 scans per block, mu = 1,
    R'/L_V = 0.7: the scans are 0.8 R' apart, so their VAD winds correlate and the block
    removes far more than the full circle's share over N (which is 2.5 times too small).
    """
    block = _exact_sector_block()
    cov, keep, sigma2 = block["cov"], block["keep"], block["sigma2"]
    pattern, radius, scale, mu = block["pattern"], block["radius"], block["scale"], block["mu"]
    phi, n_scans, t_scan = block["phi"], block["n_scans"], block["t_scan"]
    exact = (np.trace(cov) - np.trace(keep @ cov @ keep.T)) / cov.shape[0] / sigma2
    model = sector_removed_share(
        _pair_node_weights(pattern.azimuth_deg, 250.0),
        np.array([[radius / scale]]),
        np.array([mu]),
        np.array([pattern.period_s / t_scan]),
        np.array([float(n_scans)]),
        phi,
        "von_karman",
    )[0, 0]
    circle = mean_removed_share(np.array(radius / scale), phi, "von_karman", mu) / n_scans
    assert model == pytest.approx(exact, rel=0.12)
    assert exact > 2.0 * circle


def test_node_ratio_and_scale_ratio_sums_equal_the_per_point_forms(options):
    """The batched forms of the sector factor against :meth:`ATable.evaluate` with weights
    and :meth:`ATable.scale_ratio` point by point (the same interpolation, to round-off)."""
    from cwproc.physics.atable_interp import N_BINS

    common = dict(phi_deg=PHI, delta_theta_deg=DTHETA, n_lags=N_LAGS)
    inertial = get_a_table(
        PROBE,
        model="inertial",
        **common,
        **{k: v for k, v in options.items() if k != "outer_scale_range_m"},
    )
    table = get_a_table(PROBE, model="von_karman", **common, **options)
    rng = np.random.default_rng(3)
    n = 200
    lags = rng.integers(1, N_LAGS + 1, n).astype(float)
    height = rng.choice(HEIGHTS, n)
    mu = rng.uniform(0.0, 2.5, n)
    weights = rng.uniform(0.0, 1.0, (n, N_BINS))
    weights /= weights.sum(-1, keepdims=True)
    ratio = inertial.node_ratio(lags, height, mu)
    _, full = inertial.evaluate(lags, height, mu)
    _, part = inertial.evaluate(lags, height, mu, weights=weights)
    np.testing.assert_allclose(full * np.sum(ratio * weights, -1), part, rtol=1e-12)
    scales = table.outer_scales_m[::5]
    vectors = np.stack([ratio * weights, ratio], axis=1)
    sums = table.scale_ratio_sums(lags, height, mu, scales, vectors)
    for k, big_l in enumerate(scales):
        q = table.scale_ratio(lags, height, mu, big_l)
        expected = np.einsum("qn,qjn->qj", q, vectors)
        np.testing.assert_allclose(sums[:, k], expected, rtol=1e-12)


def test_sector_scans_use_the_sector_vad_removal_in_the_variance_condition(options, monkeypatch):
    """A 90 deg sector scan (scans 18 s apart, T_scan 60 s), von Karman L_V = 300 m.

    Data consistent with the sector's A_2 (its own von Karman per-node ratio, less the
    share of D(l) the block-mean VAD wind takes) and with the share of sigma_V^2 it
    removes (:func:`sector_removed_share`, 3-4 times the full circle's here) give
    eps, L_V and sigma_V^2 back; with the full circle's share (measured: L_V 27-30 % low,
    eps 4-5 % high) L_V is more than 10 % off.
    """
    from cwproc.physics.atable_interp import azimuth_bin_weights

    eps, noise, big_l, mu, interval = 0.003, 0.1, 300.0, 0.5, 18.0 / T_SCAN
    lags = np.arange(1, N_LAGS + 1, dtype=float)
    weights = azimuth_bin_weights(np.radians(250.0 - np.arange(2.0, 90.0, 2.0)))
    weights = np.broadcast_to(weights, (1, HEIGHTS.size, weights.size)).copy()
    mu_c = np.full((1, HEIGHTS.size), mu)
    inertial = get_a_table(
        PROBE,
        phi_deg=PHI,
        delta_theta_deg=DTHETA,
        n_lags=N_LAGS,
        model="inertial",
        **{k: v for k, v in options.items() if k != "outer_scale_range_m"},
    )
    table = get_a_table(
        PROBE, phi_deg=PHI, delta_theta_deg=DTHETA, n_lags=N_LAGS, model="von_karman", **options
    )
    radius = HEIGHTS / np.tan(np.deg2rad(PHI))
    # the sector's own von Karman ratio and the VAD removal in D(l) (as the stage models)
    own = np.empty((HEIGHTS.size, lags.size))
    for k, height in enumerate(HEIGHTS):
        q = table.scale_ratio(lags, height, mu, big_l)
        part = inertial.evaluate(lags, height, mu, weights=weights[0, k] * q)[1]
        circle_q = inertial.evaluate(lags, height, mu, weights=q / q.shape[-1])[1]
        own[k] = part / circle_q  # the per-node ratio normalised to the circle
    removed_d = sector_removed_d(
        weights[0],
        np.full(HEIGHTS.size, np.deg2rad(DTHETA)),
        N_LAGS,
        (radius / big_l)[:, None],
        np.full(HEIGHTS.size, mu),
        np.full(HEIGHTS.size, interval),
        np.full(HEIGHTS.size, 10.0),
        PHI,
        "von_karman",
    )[:, 0]
    full_var = spectra.variance_per_eps23("von_karman", big_l)
    d = model_d(table, eps, 0.0, mu_c, outer=big_l) * own[None] + 2 * noise**2
    d = d - eps ** (2 / 3) * full_var * removed_d[None]
    dy = np.deg2rad(DTHETA) * radius
    share = sector_removed_share(
        weights[0],
        (radius / big_l)[:, None],
        np.full(HEIGHTS.size, mu),
        np.full(HEIGHTS.size, interval),
        np.full(HEIGHTS.size, 10.0),
        PHI,
        "von_karman",
    )[:, 0]
    circle = mean_removed_share(radius / big_l, PHI, "von_karman", mu) / 10
    assert np.all(share > 2.5 * circle)
    passed = passed_variance(PROBE, dy, HEIGHTS / np.sin(np.deg2rad(PHI)), "von_karman", [big_l])
    full = spectra.variance_per_eps23("von_karman", big_l)
    var_raw = eps ** (2 / 3) * (passed[:, 0] - full * share) + noise**2
    sf = make_sf(d, mu=mu_c, variance=var_raw[None, :])
    sf["pair_azimuth_weights"] = (("time", "height", "azimuth_node"), weights)
    sf["scan_interval"] = ("time", [18.0])
    out = estimate_epsilon(sf, probe=PROBE, lag_number=3, model="von_karman", table_options=options)
    np.testing.assert_allclose(out["epsilon"].values, eps, rtol=0.03)
    np.testing.assert_allclose(out["integral_scale"].values, big_l, rtol=0.05)
    np.testing.assert_allclose(out["velocity_variance"].values, eps ** (2 / 3) * full, rtol=0.03)
    # the same data with the full circle's share (partial circles not recognised)
    monkeypatch.setattr(
        "cwproc.stages.epsilon.cells.partial_circle",
        lambda w, step: np.zeros(w.shape[:-1], bool),
    )
    circle_only = estimate_epsilon(
        sf, probe=PROBE, lag_number=3, model="von_karman", table_options=options
    )
    assert np.all(np.abs(circle_only["integral_scale"].values / big_l - 1) > 0.1)


def test_outer_scale_sector_factor_of_a_full_circle_and_a_sector():
    # the finite table's own per-node ratio (scale_ratio) relative to the inertial one:
    # 1 for a full circle (the per-node ratio is normalised to a circle mean of 1
    # there), above 1 for a 90 deg sector at mu = 1 where the outer scale cuts D most
    # along the wind (the inertial ratio alone was 4-13 % low on the exact sector,
    # tests/physics/test_atable_swept.py)
    from cwproc.physics import atable
    from cwproc.physics.atable_interp import N_BINS, azimuth_bin_weights
    from cwproc.stages.epsilon.atable_fit import outer_scale_sector_factor

    common = dict(
        phi_deg=35.0,
        delta_theta_deg=5.0,
        n_lags=3,
        height_range_m=(70.0, 140.0),
        mu_max=3.0,
        swept=False,
    )
    inert = atable.build_a_table(PROBE, atable.table_parameters(PROBE, **common))
    finite = atable.build_a_table(
        PROBE,
        atable.table_parameters(
            PROBE, model="von_karman", outer_scale_range_m=(150.0, 260.0), **common
        ),
    )
    h = np.full(3, finite.scale_height_m)
    mu = np.array([1.0, 1.0, 1.0])
    weights = np.stack(
        [
            np.full(N_BINS, 1.0 / N_BINS),
            azimuth_bin_weights(np.radians(np.arange(2.5, 90.0, 5.0))),
            np.full(N_BINS, np.nan),
        ]
    )
    lags = np.arange(1.0, 4.0)
    factor = outer_scale_sector_factor((inert, finite), lags, h, mu, weights)
    assert factor.shape == (3, finite.outer_scales_m.size, 3)
    np.testing.assert_allclose(factor[0], 1.0, atol=1e-4)
    assert np.all(factor[1] > 1.01) and np.all(np.diff(factor[1], axis=-1) > 0)
    np.testing.assert_array_equal(factor[2], 1.0)  # unknown weights: the full circle


def test_sector_vad_removal_in_d_matches_exact_block_statistics():
    """The share of sigma_V^2 the block-mean VAD wind takes from D(l) of a sector, against
    the exact covariance of the rays (the block of the test above): expected D of the
    residual pairs less that of the velocities, lags 1-4 (3-15 % of D). Measured: model
    0.0058/0.026/0.062/0.108 of sigma_V^2, exact 0.0050/0.023/0.053/0.095 (point beams,
    13-16 % high, 0.5-2 % of D)."""
    from cwproc.physics.removed_share import sector_removed_d

    block = _exact_sector_block()
    cov, keep, sigma2 = block["cov"], block["keep"], block["sigma2"]
    pattern, radius, scale, mu = block["pattern"], block["radius"], block["scale"], block["mu"]
    phi, n_scans, t_scan = block["phi"], block["n_scans"], block["t_scan"]
    az = np.radians(np.asarray(pattern.azimuth_deg))
    res = keep @ cov @ keep.T
    lags = np.arange(1, 5)
    exact, d_vel = [], []
    for lag in lags:
        a = np.concatenate([s * az.size + np.arange(az.size - lag) for s in range(n_scans)])
        b = a + lag
        d = cov[a, a] + cov[b, b] - 2 * cov[a, b]
        d_res = res[a, a] + res[b, b] - 2 * res[a, b]
        exact.append(np.mean(d - d_res) / sigma2)
        d_vel.append(np.mean(d) / sigma2)
    step = float(np.degrees(abs(az[1] - az[0])))
    model = sector_removed_d(
        _pair_node_weights(pattern.azimuth_deg, 250.0),
        np.radians([step]),
        lags.size,
        np.array([[radius / scale]]),
        np.array([mu]),
        np.array([pattern.period_s / t_scan]),
        np.array([float(n_scans)]),
        phi,
        "von_karman",
    )[0, 0]
    np.testing.assert_allclose(model, exact, rtol=0.2)
    assert np.all(np.diff(exact) > 0) and np.all(np.diff(model) > 0)
