"""Stage ``qc``: SNR, outlier and finiteness flags; nothing is dropped or changed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.physics import vad_errors as ve
from cwproc.physics.geometry import radial_velocity
from cwproc.stages.qc import robust_outliers, screen_radial_velocity
from cwproc.stages.vad import fit_vad

U, V, W = 8.0, 3.0, -0.3


def scan_dataset(
    *,
    n_scans: int = 50,
    n_rays: int = 24,
    n_gates: int = 20,
    elevation: float = 45.0,
    sigma: float = 0.3,
    seed: int = 0,
    homodyne: bool = False,
) -> xr.Dataset:
    """Full rotations of a uniform wind (U, V, W) plus seeded Gaussian noise."""
    rng = np.random.default_rng(seed)
    az = np.tile(np.arange(n_rays) * 360.0 / n_rays, n_scans)
    el = np.full(az.size, elevation)
    vr = radial_velocity(U, V, W, az, el)[:, None] + sigma * rng.standard_normal((az.size, n_gates))
    if homodyne:
        vr = np.abs(vr)
    time = np.datetime64("2024-05-01T00:00", "ns") + np.arange(az.size) * np.timedelta64(1, "s")
    return xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), vr),
            "snr": (("ray", "range"), rng.uniform(0.02, 1.0, vr.shape)),
        },
        coords={
            "time": ("ray", time),
            "azimuth": ("ray", az),
            "elevation": ("ray", el),
            "scan": ("ray", np.repeat(np.arange(n_scans), n_rays)),
            "range": ("range", 60.0 + 30.0 * np.arange(n_gates)),
        },
        attrs={"homodyne": int(homodyne), "velocity_resolution_m_s": 0.0382},
    )


def screen(ds: xr.Dataset, snr_min: float = 0.008, k: float = 4.0) -> xr.Dataset:
    return screen_radial_velocity(ds, snr_min=snr_min, outlier_threshold=k)


def inject_outliers(ds: xr.Dataset, per_group: int, seed: int) -> np.ndarray:
    """Replace ``per_group`` rays of every scan/gate by noise estimates of +-(6..20) m/s."""
    rng = np.random.default_rng(seed)
    n_rays = int((ds["scan"] == 0).sum())
    n_scans = int(ds["scan"].max()) + 1
    mask = np.zeros(ds["radial_velocity"].shape, dtype=bool)
    for g in range(ds.sizes["range"]):
        rays = np.argsort(rng.random((n_scans, n_rays)), axis=1)[:, :per_group]
        mask[(rays + n_rays * np.arange(n_scans)[:, None]).ravel(), g] = True
    jump = rng.uniform(6.0, 20.0, mask.sum()) * rng.choice([-1.0, 1.0], mask.sum())
    ds["radial_velocity"].values[mask] += jump
    return mask


def test_flags_low_snr_and_non_finite_and_keeps_values() -> None:
    ds = scan_dataset(n_scans=3, seed=1)
    ds["snr"].values[5, :4] = 0.001
    ds["snr"].values[6, 0] = np.nan
    ds["radial_velocity"].values[7, 2] = np.nan
    ds["radial_velocity"].values[5, 1] = np.inf  # low SNR and not finite
    before = ds["radial_velocity"].values.copy()
    out = screen(ds)
    flag = out["qc_flag_radial"].values
    assert out["qc_flag_radial"].dims == ("ray", "range") and flag.dtype == np.int8
    assert flag[5, 0] == 1 and flag[5, 2] == 1 and flag[6, 0] == 1
    assert flag[7, 2] == 4
    assert flag[5, 1] == 1 | 4
    np.testing.assert_array_equal(out["radial_velocity"].values, before)
    assert out.sizes == ds.sizes
    assert out["qc_flag_radial"].attrs["snr_min"] == 0.008


def test_clean_gaussian_data_has_few_false_outliers() -> None:
    out = screen(scan_dataset(n_scans=100, seed=2))
    flag = out["qc_flag_radial"].values
    # 4 scaled MADs: 6e-5 of Gaussian data lie beyond 4 sigma, but the MAD of 24
    # residuals scatters; a direct simulation of one LS pass gives 0.21 %, the refit
    # passes add a little: below 0.5 %
    assert np.mean(flag == 2) < 5e-3
    assert np.all(flag != 1)  # SNR drawn above the threshold


def test_injected_outliers_are_flagged_and_do_not_bias_the_fit() -> None:
    sigma, phi = 0.3, 45.0
    ds = scan_dataset(n_scans=60, sigma=sigma, elevation=phi, seed=3)
    injected = inject_outliers(ds, per_group=3, seed=4)
    flag = screen(ds)["qc_flag_radial"].values
    found = flag == 2
    assert found[injected].mean() > 0.99
    assert found[~injected].mean() < 5e-3
    wind = fit_vad(screen(ds), min_rays=6, max_gap_deg=120.0)
    predicted = ve.rms_errors(
        ve.least_squares_weights(np.arange(21) * 360.0 / 24.0, phi), sigma
    )  # 21 of 24 rays; the layout barely matters at this level
    errors = np.stack([wind["v"] - V, wind["u"] - U, wind["w"] - W]).reshape(3, -1)
    n = errors.shape[1]
    for e, p in zip(errors, predicted, strict=True):
        assert np.sqrt(np.mean(e**2)) < 1.2 * p
        assert abs(np.mean(e)) < 4.0 * p / np.sqrt(n)
    # without screening the same data give far larger errors: the test can fail
    raw = fit_vad(ds, min_rays=6, max_gap_deg=120.0)
    assert np.sqrt(np.mean((raw["u"].values - U) ** 2)) > 5 * predicted[1]


def test_noise_gate_contamination_with_a_bad_first_fit() -> None:
    """Six of 24 rays (25 %) are noise estimates: the first LS fit is badly pulled."""
    ds = scan_dataset(n_scans=30, n_gates=10, seed=5)
    injected = inject_outliers(ds, per_group=6, seed=6)
    found = screen(ds)["qc_flag_radial"].values == 2
    assert found[injected].mean() > 0.97
    assert found[~injected].mean() < 0.01


def test_homodyne_outliers_use_the_magnitude_model() -> None:
    ds = scan_dataset(n_scans=30, n_gates=6, n_rays=50, elevation=60.0, sigma=0.1,
                      homodyne=True, seed=7)  # fmt: skip
    rng = np.random.default_rng(8)
    rows = rng.choice(ds.sizes["ray"], 40, replace=False)
    ds["radial_velocity"].values[rows, 2] += 5.0
    flag = screen(ds)["qc_flag_radial"].values
    assert np.all(flag[rows, 2] == 2)
    assert np.mean(flag == 2) < 40 / flag.size + 3e-3
    assert "homodyne" in screen(ds)["qc_flag_radial"].attrs["method"]


def test_rays_outside_scans_get_no_outlier_test() -> None:
    ds = scan_dataset(n_scans=2, seed=9)
    ds["scan"] = ("ray", np.full(ds.sizes["ray"], -1))
    ds["radial_velocity"].values[3, 3] += 50.0
    assert np.all(screen(ds)["qc_flag_radial"].values == 0)


def test_without_snr_the_snr_test_is_skipped() -> None:
    out = screen(scan_dataset(n_scans=2, seed=10).drop_vars("snr"))
    assert np.all(out["qc_flag_radial"].values != 1)
    assert "not applied" in out["qc_flag_radial"].attrs["snr_min"]


def test_missing_radial_velocity_is_a_clear_error() -> None:
    with pytest.raises(CwprocError, match="radial_velocity"):
        screen(scan_dataset(n_scans=1).drop_vars("radial_velocity"))


def test_robust_outliers_rule() -> None:
    # 18 residuals 0, +-1 (MAD = 1, scaled 1.4826): 6 is an outlier at k = 4, 5.9 is not
    r18 = np.array([0, 1, -1] * 5 + [0, 5.9, 6.0], dtype=float)
    flagged = robust_outliers(r18[None, :, None], np.ones((1, r18.size, 1), bool), 4.0, 0.01)
    assert list(np.flatnonzero(flagged[0, :, 0])) == [17]
    # 12 rays (fewer than FEW_RAYS): k = 4 x 1.5 = 6 scaled MADs, 8.9 m s-1: 9 is, 6 is not
    r = np.array([0, 1, -1, 0, 1, -1, 0, 6.0, 9.0, 0, 1, -1], dtype=float)
    flagged = robust_outliers(r[None, :, None], np.ones((1, r.size, 1), bool), 4.0, 0.01)
    assert list(np.flatnonzero(flagged[0, :, 0])) == [8]
    # fewer than 6 valid entries: no test
    few = np.zeros((1, r.size, 1), bool)
    few[0, [0, 1, 2, 8, 9], 0] = True
    assert not robust_outliers(r[None, :, None], few, 4.0, 0.01).any()


def test_real_stare_file_is_screened_without_change(real_data: Path) -> None:
    halo = pytest.importorskip("cwproc.io.halo")
    ds = halo.read_hpl(real_data / "hpl" / "eriswil-2022-12-14-Stare_91_20221214_11.hpl")
    out = screen(ds)
    flag = out["qc_flag_radial"].values
    np.testing.assert_array_equal(out["radial_velocity"].values, ds["radial_velocity"].values)
    low = ~(ds["snr"].values >= 0.008)
    np.testing.assert_array_equal((flag & 1) == 1, low)
    assert np.all(flag & 2 == 0)  # a stare has no conical scan: no outlier test


def test_outlier_passes_on_changed_groups_flag_as_refitting_every_group() -> None:
    """The linear outlier passes refit only the (scan, gate) groups whose rays differ
    from those of their last fit (the first pass: the groups with a ray flagged by the
    L1 fit, the others keep the least-squares residuals of all their rays), each alone,
    and after the first pass test only the groups that changed: the flags equal those
    of refitting and testing every group in every pass (a least-squares fit per group is
    its own), on noisy scans with wild estimates where the flags change from pass to
    pass."""
    from cwproc.physics.geometry import beam_unit_vector
    from cwproc.physics.vad_least_squares import (
        fit_least_absolute,
        linear_residuals,
        linear_start,
        ray_rows,
        row_residuals,
    )
    from cwproc.stages import qc

    rng = np.random.default_rng(3)
    n_scans, n_rays, n_gates = 12, 24, 15
    az = np.tile(np.arange(n_rays) * 15.0, (n_scans, 1)) + rng.uniform(0, 1, (n_scans, 1))
    design = beam_unit_vector(az, np.full(az.shape, 60.0))
    values = design @ np.array([6.0, -2.0, 0.2]) + 0.3 * rng.standard_normal((n_gates, 1, 1))
    values = np.moveaxis(values, 0, -1) + 0.4 * rng.standard_normal((n_scans, n_rays, n_gates))
    wild = rng.random(values.shape) < 0.12
    values[wild] = rng.uniform(-8, 8, wild.sum())
    base = rng.random(values.shape) > 0.05
    _, residuals = fit_least_absolute(values, design, base, homodyne=False)
    use, n = qc.tested_entries(base)
    first = qc._outliers(residuals, use, n, 4.0, 0.04)
    reference, history = first, [first]
    for _ in range(qc.OUTLIER_PASSES):  # every group refitted and tested in every pass
        again = qc._outliers(linear_residuals(values, design, base & ~reference), use, n, 4.0, 0.04)
        history.append(again)
        if np.array_equal(again, reference):
            break
        reference = again
    changed = [np.any(a != b, axis=1).sum() for a, b in zip(history[1:], history[:-1], strict=True)]
    assert changed[0] > changed[1] > 0  # later passes change fewer groups, but some
    rows = ray_rows(values, base)
    least_squares = row_residuals(rows[0], design, linear_start(values, design, base, rows)[1])
    got = qc._linear_passes(values, design, base, first, use, n, 4.0, 0.04, least_squares)
    assert np.array_equal(got, reference)
