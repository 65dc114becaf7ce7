"""Stage ``vad``: recovery of known winds within the VAD error theory (VAD accuracy paper).

Synthetic scans are built here from V_r = w sin(phi) + cos(phi)(u sin(theta) +
v cos(theta)) plus seeded Gaussian noise of std sigma. The predicted RMS errors come
from :mod:`cwproc.physics.vad_errors` with x = north (v), y = east (u), z = up (w).
Monte-Carlo tolerances: the RMS of n Gaussian errors has relative standard error
1/sqrt(2n); tests allow 4 of them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from cwproc.errors import CwprocError
from cwproc.metadata.products import apply_metadata, undeclared_variables
from cwproc.physics import vad_errors as ve
from cwproc.physics.geometry import beam_unit_vector, radial_velocity, speed_and_direction
from cwproc.physics.vad_least_squares import fit_homodyne
from cwproc.references import SMALIKHO_2020, VAD_ACCURACY
from cwproc.stages import vad
from cwproc.stages.vad import fit_vad

T0 = np.datetime64("2024-05-01T00:00:00", "ns")


def scan_dataset(
    u: float | np.ndarray = 6.0,
    v: float | np.ndarray = -4.0,
    w: float | np.ndarray = 0.4,
    *,
    n_scans: int = 4,
    n_rays: int = 24,
    n_gates: int = 10,
    elevation: float = 35.3,
    sigma: float = 0.3,
    seed: int = 0,
    homodyne: bool = False,
    scan_seconds: float = 24.0,
) -> xr.Dataset:
    """A canonical scan dataset of ``n_scans`` full rotations with known wind."""
    rng = np.random.default_rng(seed)
    az = np.tile(np.arange(n_rays) * 360.0 / n_rays, n_scans)
    el = np.full(az.size, elevation)
    ranges = 50.0 + 30.0 * np.arange(n_gates)
    truth = radial_velocity(
        np.broadcast_to(u, (n_gates,)),
        np.broadcast_to(v, (n_gates,)),
        np.broadcast_to(w, (n_gates,)),
        az[:, None],
        el[:, None],
    )
    vr = truth + sigma * rng.standard_normal(truth.shape)
    if homodyne:
        vr = np.abs(vr)
    dt = scan_seconds / n_rays
    time = T0 + (np.arange(az.size) * dt * 1e9).astype("timedelta64[ns]")
    return xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), vr),
            "snr": (("ray", "range"), np.full(vr.shape, 0.5)),
        },
        coords={
            "time": ("ray", time),
            "azimuth": ("ray", az),
            "elevation": ("ray", el),
            "scan": ("ray", np.repeat(np.arange(n_scans), n_rays)),
            "range": ("range", ranges),
        },
        attrs={"instrument": "synthetic", "homodyne": int(homodyne)},
    )


def fit(ds: xr.Dataset, **kw: object) -> xr.Dataset:
    args = {"min_rays": 6, "max_gap_deg": 120.0}
    args.update(kw)
    return fit_vad(ds, **args)  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------
# accuracy against theory
# --------------------------------------------------------------------------------------


def test_recovers_known_wind_within_theory() -> None:
    sigma, phi, n = 0.3, 35.3, 24
    wind = fit(scan_dataset(n_scans=100, n_gates=40, sigma=sigma, elevation=phi, seed=1))
    predicted = ve.rms_error_full_circle(n, phi, sigma)  # (v, u, w)
    errors = {
        "v": wind["v"].values + 4.0,
        "u": wind["u"].values - 6.0,
        "w": wind["w"].values - 0.4,
    }
    n_real = errors["u"].size
    for name, rms_pred in zip(("v", "u", "w"), predicted, strict=True):
        e = errors[name]
        assert np.max(np.abs(e)) < 5.0 * rms_pred, name
        rms = np.sqrt(np.mean(e**2))
        assert rms == pytest.approx(rms_pred, rel=4.0 / np.sqrt(2 * n_real)), name
        # no bias: the mean error is within 4 standard errors of zero
        assert abs(np.mean(e)) < 4.0 * rms_pred / np.sqrt(n_real), name
        # the reported standard errors agree with the theory on average
        reported = np.sqrt(np.mean(wind[f"{name}_error"].values ** 2))
        assert reported == pytest.approx(rms_pred, rel=0.05), name
    assert np.all(wind["qc_flag"].values == 0)
    assert np.all(wind["n_rays"].values == n)
    assert np.allclose(wind["max_azimuth_gap"].values, 15.0)
    assert np.sqrt(np.mean(wind["residual_std"].values ** 2)) == pytest.approx(sigma, rel=0.02)


def test_missing_sector_rms_grows_as_theory_predicts() -> None:
    """A 60 deg sector centred on north removed: v (along the bisector) degrades."""
    sigma, phi, n = 0.5, 35.3, 72
    ds = scan_dataset(n_scans=200, n_rays=n, n_gates=20, sigma=sigma, elevation=phi, seed=2)
    centred = (ds["azimuth"] + 180.0) % 360.0 - 180.0
    ds["radial_velocity"] = ds["radial_velocity"].where(np.abs(centred) >= 30.0)
    wind = fit(ds)
    az = ve.uniform_azimuths_deg(n, 60.0)
    predicted = ve.rms_errors(ve.least_squares_weights(az, phi), sigma)  # (v, u, w)
    full = ve.rms_error_full_circle(n, phi, sigma)
    n_real = wind["v"].size
    tolerance = 4.0 / np.sqrt(2 * n_real)
    rms_v = np.sqrt(np.mean((wind["v"].values + 4.0) ** 2))
    rms_u = np.sqrt(np.mean((wind["u"].values - 6.0) ** 2))
    rms_w = np.sqrt(np.mean((wind["w"].values - 0.4) ** 2))
    assert rms_v == pytest.approx(predicted[0], rel=tolerance)
    assert rms_u == pytest.approx(predicted[1], rel=tolerance)
    assert rms_w == pytest.approx(predicted[2], rel=tolerance)
    # theory: +22.6 % along the bisector, +1.1 % across it
    assert predicted[0] / full[0] == pytest.approx(1.2257, abs=1e-3)
    assert rms_v / full[0] > 1.15
    assert np.all(wind["n_rays"].values == az.size)
    np.testing.assert_allclose(wind["max_azimuth_gap"].values, 60.0)  # rays at +-30 kept


def test_speed_and_direction_errors_match_scatter() -> None:
    wind = fit(scan_dataset(n_scans=100, n_gates=30, sigma=0.5, seed=3))
    for name in ("wind_speed", "wind_direction"):
        scatter = np.std(wind[name].values)
        reported = np.sqrt(np.mean(wind[f"{name}_error"].values ** 2))
        assert reported == pytest.approx(scatter, rel=0.1), name
    assert np.mean(wind["wind_speed"].values) == pytest.approx(np.hypot(6.0, 4.0), rel=0.01)
    # wind from the north-west: u > 0 (towards east), v < 0 (towards south)
    expected_direction = np.rad2deg(np.arctan2(-6.0, 4.0)) % 360.0
    assert np.mean(wind["wind_direction"].values) == pytest.approx(expected_direction, abs=0.5)


# --------------------------------------------------------------------------------------
# flags
# --------------------------------------------------------------------------------------


def test_too_few_rays_and_gap_flags() -> None:
    ds = scan_dataset(n_scans=3, sigma=0.1, seed=4)
    vr = ds["radial_velocity"].values
    ray_in_scan = np.arange(ds.sizes["ray"]) % 24
    scan = ds["scan"].values
    # scan 0: only 5 rays left in gate 0 (every 5th ray) -> too few
    vr[(scan == 0) & (ray_in_scan % 5 != 0), 0] = np.nan
    # scan 1: 9 consecutive rays missing in gate 1 -> a 150 deg gap
    vr[(scan == 1) & (ray_in_scan >= 3) & (ray_in_scan < 12), 1] = np.nan
    # scan 2: 3 rays in gate 2 -> determined but no residual degree of freedom
    vr[(scan == 2) & ~np.isin(ray_in_scan, [0, 8, 16]), 2] = np.nan
    # scan 2: 2 rays in gate 3 -> not determined
    vr[(scan == 2) & ~np.isin(ray_in_scan, [0, 12]), 3] = np.nan
    wind = fit(ds)
    flag = wind["qc_flag"].values
    assert wind["n_rays"].values[0, 0] == 5 and flag[0, 0] & 1
    assert flag[0, 0] & 4 == 0  # 5 rays fit well: only "too few"
    assert wind["max_azimuth_gap"].values[1, 1] == pytest.approx(150.0)
    assert flag[1, 1] == 2
    assert fit(ds, max_gap_deg=160.0)["qc_flag"].values[1, 1] == 0
    assert flag[2, 2] == 1 | 4 and np.isfinite(wind["u"].values[2, 2])
    assert np.isnan(wind["u_error"].values[2, 2])
    assert flag[2, 3] == 1 | 2 | 4 and np.isnan(wind["u"].values[2, 3])
    # everything else is good
    good = np.ones(flag.shape, dtype=bool)
    good[[0, 1, 2, 2], [0, 1, 2, 3]] = False
    assert np.all(flag[good] == 0)


def test_large_residuals_flag_bad_fit() -> None:
    wind = fit(scan_dataset(n_scans=2, sigma=6.0, seed=5))
    assert np.all(wind["qc_flag"].values & 4)
    assert np.all(wind["residual_std"].values > 3.0)
    relaxed = fit(scan_dataset(n_scans=2, sigma=6.0, seed=5), max_residual_std=20.0)
    assert np.all(relaxed["qc_flag"].values == 0)


def test_uses_only_rays_with_flag_zero() -> None:
    ds = scan_dataset(n_scans=2, sigma=0.1, seed=6)
    flag = np.zeros(ds["radial_velocity"].shape, dtype=np.int8)
    ds["radial_velocity"].values[::4, :] += 30.0  # corrupted ...
    flag[::4, :] = 2  # ... and flagged
    ds["qc_flag_radial"] = (("ray", "range"), flag)
    wind = fit(ds)
    assert np.all(wind["n_rays"].values == 18)
    predicted = ve.rms_errors(
        ve.least_squares_weights(np.arange(24)[np.arange(24) % 4 != 0] * 15.0, 35.3), 0.1
    )
    assert np.max(np.abs(wind["u"].values - 6.0)) < 5 * predicted[1]


# --------------------------------------------------------------------------------------
# elevations, schema, errors
# --------------------------------------------------------------------------------------


def test_no_conical_scan_is_a_clear_error() -> None:
    stare = scan_dataset(n_scans=2, elevation=90.0)
    with pytest.raises(CwprocError, match="no conical scan"):
        fit(stare)
    unassigned = scan_dataset(n_scans=2)
    unassigned["scan"] = ("ray", np.full(unassigned.sizes["ray"], -1))
    with pytest.raises(CwprocError, match="no conical scan"):
        fit(unassigned)


def test_missing_variable_is_a_clear_error() -> None:
    with pytest.raises(CwprocError, match="lacks scan"):
        fit(scan_dataset(n_scans=1).drop_vars("scan"))


def test_most_common_elevation_is_used_and_recorded() -> None:
    low = scan_dataset(n_scans=4, elevation=60.0, seed=7)
    high = scan_dataset(n_scans=2, elevation=75.0, seed=8)
    high = high.assign_coords(scan=high["scan"] + 4, time=high["time"] + np.timedelta64(5, "m"))
    wind = fit(xr.concat([low, high], dim="ray"))
    assert wind.sizes["time"] == 4
    assert list(wind["scan"].values) == [0, 1, 2, 3]
    assert wind.attrs["vad_elevation_deg"] == pytest.approx(60.0)
    assert wind.attrs["vad_scans_other_elevation"] == 2
    np.testing.assert_allclose(wind["height"].values, wind["range"].values * np.sin(np.pi / 3))


def test_over_zenith_pointing_is_normalised() -> None:
    ds = scan_dataset(n_scans=2, elevation=70.0, sigma=0.05, seed=9)
    flipped = ds.assign_coords(
        azimuth=(ds["azimuth"] + 180.0) % 360.0, elevation=180.0 - ds["elevation"]
    )
    np.testing.assert_allclose(fit(flipped)["u"].values, fit(ds)["u"].values, atol=1e-10)


def test_product_schema() -> None:
    ds = scan_dataset(n_scans=3, n_gates=5)
    wind = fit(ds)
    assert dict(wind.sizes) == {"time": 3, "height": 5}
    for name in (
        "u", "v", "w", "wind_speed", "wind_direction", "u_error", "v_error", "w_error",
        "wind_speed_error", "wind_direction_error", "residual_std", "n_rays",
        "max_azimuth_gap", "qc_flag",
    ):  # fmt: skip
        assert wind[name].dims == ("time", "height"), name
    assert wind["range"].dims == ("height",)
    assert wind["scan"].dims == ("time",) and wind["elevation"].dims == ("time",)
    assert wind["qc_flag"].dtype == np.int8
    assert undeclared_variables(wind) == []
    # time = mean time of the scan's rays: the middle of a 24 s rotation of 24 rays
    expected = T0 + np.timedelta64(11_500, "ms")
    assert wind["time"].values[0] == expected
    # the stage records its method; the citations of the variables come from the metadata
    assert "least squares" in wind["u"].attrs["method"]
    written = apply_metadata(wind, product="wind")
    assert f"{SMALIKHO_2020}, eqs. 1 and 8" in written["u"].attrs["references"]
    assert f"{VAD_ACCURACY}, section 4" in written["u_error"].attrs["references"]
    assert f"{VAD_ACCURACY}, sections 2-4" in wind.attrs["vad_references"]


def test_chunked_solution_equals_single_block(monkeypatch: pytest.MonkeyPatch) -> None:
    ds = scan_dataset(n_scans=7, seed=10)
    whole = fit(ds)
    monkeypatch.setattr(vad, "CHUNK_ELEMENTS", 24 * 10 * 2)  # two scans per chunk
    xr.testing.assert_identical(fit(ds), whole)


# --------------------------------------------------------------------------------------
# homodyne (ZephIR): |V_r| only
# --------------------------------------------------------------------------------------


def homodyne_dataset(seed: int = 11, n_scans: int = 60) -> xr.Dataset:
    # ZephIR: 30 deg from the vertical (phi = 60 deg), 50 lines of sight per rotation
    return scan_dataset(
        u=-7.0, v=3.0, w=0.2, n_scans=n_scans, n_rays=50, n_gates=8, elevation=60.0,
        sigma=0.15, seed=seed, homodyne=True, scan_seconds=1.0,
    )  # fmt: skip


TRUE_DIRECTION = float(np.rad2deg(np.arctan2(7.0, -3.0)) % 360.0)  # from ESE ~ 113 deg


def test_homodyne_recovers_speed_and_direction() -> None:
    wind = fit(homodyne_dataset(), reference_direction_deg=TRUE_DIRECTION + 60.0)
    predicted = ve.rms_error_full_circle(50, 60.0, 0.15)
    assert np.max(np.abs(wind["u"].values + 7.0)) < 5 * predicted[1]
    assert np.max(np.abs(wind["v"].values - 3.0)) < 5 * predicted[0]
    assert np.max(np.abs(wind["w"].values - 0.2)) < 5 * predicted[2]
    speed_error = wind["wind_speed"].values - np.hypot(7.0, 3.0)
    direction_error = (wind["wind_direction"].values - TRUE_DIRECTION + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(speed_error)) < 5 * predicted[0]
    assert np.max(np.abs(direction_error)) < 5 * np.mean(wind["wind_direction_error"].values)
    assert np.all(wind["qc_flag"].values == 0)
    assert "configured" in wind.attrs["vad_homodyne_ambiguity"]
    assert "homodyne" in wind["u"].attrs["method"]


def test_homodyne_ambiguity_follows_the_reference() -> None:
    ds = homodyne_dataset(n_scans=5)
    right = fit(ds, reference_direction_deg=TRUE_DIRECTION - 80.0)
    wrong = fit(ds, reference_direction_deg=TRUE_DIRECTION + 180.0 - 30.0)
    np.testing.assert_allclose(wrong["u"].values, -right["u"].values)
    np.testing.assert_allclose(wrong["w"].values, -right["w"].values)
    assert np.all(np.abs(right["u"].values + 7.0) < 0.2)


def test_homodyne_measured_reference_and_missing_reference() -> None:
    ds = homodyne_dataset(n_scans=3)
    with pytest.raises(CwprocError, match="ambiguous by 180 degrees"):
        fit(ds)
    ds.attrs["reference_direction_deg"] = TRUE_DIRECTION + 20.0
    from_attr = fit(ds)
    assert "attribute" in from_attr.attrs["vad_homodyne_ambiguity"]
    assert np.all(np.abs(from_attr["u"].values + 7.0) < 0.2)
    # a measured direction per ray (e.g. a met mast) takes precedence over the attribute
    ds["reference_direction"] = ("ray", np.full(ds.sizes["ray"], TRUE_DIRECTION - 170.0))
    measured = fit(ds)
    assert "measured" in measured.attrs["vad_homodyne_ambiguity"]
    np.testing.assert_allclose(measured["u"].values, -from_attr["u"].values)


@pytest.mark.parametrize("spelling", ["false", "0", 0, False, np.int8(0)])
def test_homodyne_false_in_any_spelling_is_heterodyne(spelling: object) -> None:
    """``bool("false")`` is True; the one parser (cwproc.io.scan_join) reads it as 0."""
    ds = scan_dataset(n_scans=2, seed=14)
    signed = fit(ds)
    ds.attrs["homodyne"] = spelling
    xr.testing.assert_identical(fit(ds).drop_attrs(), signed.drop_attrs())
    assert "homodyne" not in fit(ds).attrs["vad_method"]


def test_explicit_homodyne_argument_overrides_the_attribute() -> None:
    ds = homodyne_dataset(n_scans=2)
    ds.attrs["homodyne"] = "false"  # wrong on purpose: |V_r| data
    wind = fit(ds, homodyne=True, reference_direction_deg=TRUE_DIRECTION)
    assert "homodyne" in wind.attrs["vad_method"]
    assert np.all(np.abs(wind["u"].values + 7.0) < 0.2)
    ds.attrs["homodyne"] = "yes"
    with pytest.raises(CwprocError, match="homodyne is 'yes'"):
        fit(ds)


# --------------------------------------------------------------------------------------
# real files
# --------------------------------------------------------------------------------------


def test_real_files_fail_clearly_or_are_flagged(real_data: Path) -> None:
    halo = pytest.importorskip("cwproc.io.halo")
    from cwproc.stages.qc import screen_radial_velocity

    # a user-defined stepped scan (no 360 degree rotation): a plain-sentence error
    user5 = halo.read_hpl(real_data / "hpl" / "User5_96_20190308_200500.hpl")
    with pytest.raises(CwprocError, match="no conical scan"):
        fit(screen_radial_velocity(user5, snr_min=0.008, outlier_threshold=4.0))
    # the Soverato VAD sample holds 2 rays of a 6-ray scan: no wind, every gate flagged
    vad_file = halo.read_hpl(real_data / "hpl" / "soverato-2021-10-01-VAD_194_20210624_170110.hpl")
    wind = fit(screen_radial_velocity(vad_file, snr_min=0.008, outlier_threshold=4.0))
    assert wind.sizes["time"] == 1
    assert wind.attrs["vad_elevation_deg"] == pytest.approx(75.0)
    assert np.all(np.isnan(wind["u"].values))
    assert np.all(wind["qc_flag"].values & 1) and np.all(wind["qc_flag"].values & 4)


# --------------------------------------------------------------------------------------
# properties
# --------------------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(
    u=st.floats(-30, 30),
    v=st.floats(-30, 30),
    w=st.floats(-3, 3),
    elevation=st.floats(5, 85),
    n_rays=st.integers(4, 40),
    offset=st.floats(0, 360),
)
def test_noise_free_scans_are_recovered_exactly(
    u: float, v: float, w: float, elevation: float, n_rays: int, offset: float
) -> None:
    ds = scan_dataset(u, v, w, n_scans=2, n_rays=n_rays, n_gates=3, elevation=elevation,
                      sigma=0.0)  # fmt: skip
    ds = ds.assign_coords(azimuth=(ds["azimuth"] + offset) % 360.0)
    ds["radial_velocity"] = (
        ("ray", "range"),
        np.broadcast_to(
            radial_velocity(u, v, w, ds["azimuth"].values, elevation)[:, None], (2 * n_rays, 3)
        ).copy(),
    )
    wind = fit(ds, min_rays=3)
    np.testing.assert_allclose(wind["u"].values, u, atol=1e-8)
    np.testing.assert_allclose(wind["v"].values, v, atol=1e-8)
    np.testing.assert_allclose(wind["w"].values, w, atol=1e-8)


def test_ray_order_does_not_matter() -> None:
    ds = scan_dataset(n_scans=3, seed=12)
    order = np.random.default_rng(13).permutation(ds.sizes["ray"])
    shuffled = fit(ds.isel(ray=order))
    xr.testing.assert_allclose(shuffled, fit(ds))


def test_wrong_dimensions_are_a_clear_error() -> None:
    ds = scan_dataset(n_scans=1).transpose("range", "ray")
    with pytest.raises(CwprocError, match=r"dimensions \(ray, range\)"):
        fit(ds)


@settings(max_examples=60, deadline=None, derandomize=True)
@example(u=0.0, v=2.0, w=0.75, elevation=52.0, n_rays=8)  # converged to v 1.16, w 1.13
@given(
    u=st.floats(-20, 20),
    v=st.floats(-20, 20),
    w=st.floats(-2, 2),
    elevation=st.floats(30, 75),
    n_rays=st.integers(8, 60),
)
def test_noise_free_homodyne_scans_are_recovered_exactly(
    u: float, v: float, w: float, elevation: float, n_rays: int
) -> None:
    """|V_r| only: the Gauss-Newton fit finds the global minimum (zero residual)."""
    # the fit is ambiguous only through the overall sign; a reference within 60 deg of
    # the true direction resolves it (below ~1e-3 m s-1 the direction is undefined)
    assume(np.hypot(u, v) > 1e-3)
    ds = scan_dataset(u, v, w, n_scans=1, n_rays=n_rays, n_gates=2, elevation=elevation,
                      sigma=0.0, homodyne=True)  # fmt: skip
    direction = float(speed_and_direction(u, v)[1])
    wind = fit(ds, min_rays=3, reference_direction_deg=direction + 60.0)
    np.testing.assert_allclose(wind["u"].values, u, atol=1e-7)
    np.testing.assert_allclose(wind["v"].values, v, atol=1e-7)
    np.testing.assert_allclose(wind["w"].values, w, atol=1e-7)


def test_homodyne_counterexample_of_the_start_grid_is_fitted_exactly() -> None:
    """Issue 16: 8 rays, phi = 52 deg, u = 0, v = 2, w = 0.75 converged from the old
    half-circle start grid to v = 1.16, w = 1.13 with qc_flag 0 (a local minimum of
    ``sum (|V_r| - |A beta|)^2`` accepted as good)."""
    ds = scan_dataset(0.0, 2.0, 0.75, n_scans=1, n_rays=8, n_gates=1, elevation=52.0,
                      sigma=0.0, homodyne=True)  # fmt: skip
    wind = fit(ds, min_rays=3, reference_direction_deg=180.0)  # v > 0: wind from the south
    np.testing.assert_allclose(
        [wind["u"].item(), wind["v"].item(), wind["w"].item()], [0.0, 2.0, 0.75], atol=1e-9
    )
    assert wind["residual_std"].item() < 1e-9
    assert wind["qc_flag"].item() == 0


def _arc_patterns(n_rays: int) -> np.ndarray:
    """Every sign pattern +1 on a contiguous arc of rays, -1 elsewhere (and all +1)."""
    patterns = [np.ones(n_rays)]
    for start in range(n_rays):
        for length in range(1, n_rays):
            p = -np.ones(n_rays)
            p[(start + np.arange(length)) % n_rays] = 1.0
            patterns.append(p)
    return np.array(patterns)


@pytest.mark.parametrize(("n_rays", "elevation"), [(6, 75.0), (8, 52.0), (12, 30.0)])
def test_homodyne_fit_reaches_the_global_minimum_with_noise(n_rays: int, elevation: float) -> None:
    """Noisy |V_r|: the fitted cost equals the least cost over all arc sign patterns.

    For rays at one elevation every beta has an arc sign pattern s, and
    ``sum (|V_r| - |A beta|)^2 >= min_b sum (s |V_r| - A b)^2``, so the least linear-fit
    cost over the arcs is the global minimum (brute force over all R (R - 1) + 1 arcs).
    The old start grid missed it in about 1 % of such cells.
    """
    rng = np.random.default_rng(n_rays)
    n_cells = 400
    scale = np.where(rng.random(n_cells) < 0.4, 1.0, 10.0)  # weak and strong winds
    beta_true = np.column_stack(
        [rng.uniform(-1, 1, n_cells) * scale, rng.uniform(-1, 1, n_cells) * scale,
         rng.uniform(-2, 2, n_cells)]
    )  # fmt: skip
    az = np.tile(np.arange(n_rays) * 360.0 / n_rays, (n_cells, 1))
    design = beam_unit_vector(az, elevation)  # (S, R, 3)
    noise = 0.3 * rng.standard_normal((n_cells, n_rays))
    y = np.abs(np.einsum("srk,sk->sr", design, beta_true) + noise)
    fitted = fit_homodyne(y[..., None], design, np.ones((n_cells, n_rays, 1), bool))
    cost = np.sum(fitted.residuals[..., 0] ** 2, axis=1)
    signed = y[:, None, :] * _arc_patterns(n_rays)[None]  # (S, P, R)
    linear = np.einsum("skr,spr->spk", np.linalg.pinv(design), signed)
    model = np.abs(np.einsum("srk,spk->spr", design, linear))
    best = np.min(np.sum((y[:, None, :] - model) ** 2, axis=2), axis=1)
    np.testing.assert_allclose(cost, best, rtol=1e-9, atol=1e-12)
    assert np.all(fitted.converged)


@pytest.mark.parametrize(("u", "v", "w"), [(0.3, 0.2, 1.5), (0.05, -0.1, -1.0)])
def test_homodyne_weak_wind_strong_updraft(u: float, v: float, w: float) -> None:
    """|w sin(phi)| > V_h cos(phi): |V_r| never changes sign round the circle."""
    ds = scan_dataset(u, v, w, n_scans=1, n_rays=50, n_gates=1, elevation=60.0, sigma=0.0,
                      homodyne=True)  # fmt: skip
    wind = fit(ds, reference_direction_deg=float(speed_and_direction(u, v)[1]) - 45.0)
    np.testing.assert_allclose(
        [wind["u"].item(), wind["v"].item(), wind["w"].item()], [u, v, w], atol=1e-9
    )


def test_azimuth_gap_of_full_and_partial_gates_is_the_sorted_gap() -> None:
    """azimuth_gap: gates with every ray valid take their scan's gap, the others their
    own; each equals the largest step between its sorted valid azimuths or across 360
    (first + 360 - last), to the bit; 360 with fewer than two rays."""
    from cwproc.stages.vad import azimuth_gap

    rng = np.random.default_rng(8)
    n_scans, n_rays, n_gates = 6, 24, 9
    azimuth = np.mod(np.arange(n_rays) * 15.0 + rng.uniform(0, 15, (n_scans, 1)), 360.0)
    valid = rng.random((n_scans, n_rays, n_gates)) > 0.3
    valid[:, :, :4] = True  # full gates
    valid[0, :, 5] = False
    valid[1, :, 5] = False
    valid[1, 3, 5] = True  # one ray
    got = azimuth_gap(azimuth, valid)
    for s in range(n_scans):
        for g in range(n_gates):
            az = np.sort(azimuth[s, valid[s, :, g]])
            want = 360.0 if az.size < 2 else max(np.diff(az).max(), az[0] + 360.0 - az[-1])
            assert got[s, g] == want, (s, g)
    assert got[0, 5] == got[1, 5] == 360.0
