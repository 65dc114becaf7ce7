"""Scan segmentation (assign_scans) and concatenation of files (concat_scans)."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from cwproc.errors import CwprocError
from cwproc.io.halo import read_hpl
from cwproc.io.scan_join import assign_scans, concat_scans, is_homodyne, parse_homodyne
from cwproc.physics.scan_numbering import azimuth_steps, scan_indices, scan_indices_of_runs

T0 = np.datetime64("2024-06-01T12:00:00", "ns")


def scan_ds(
    azimuth,
    elevation,
    seconds,
    *,
    gates: int = 5,
    gate_m: float = 30.0,
    name: str = "f.hpl",
    scan_type: str = "VAD",
    seed: int = 0,
) -> xr.Dataset:
    """A small canonical scan dataset with the given pointing and times (s after T0)."""
    azimuth = np.asarray(azimuth, dtype=float)
    n = azimuth.size
    elevation = np.broadcast_to(np.asarray(elevation, dtype=float), (n,)).copy()
    seconds = np.asarray(seconds, dtype=float)
    rng = np.random.default_rng(seed)
    time = T0 + np.rint(seconds * 1e9).astype("timedelta64[ns]")
    return xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), rng.normal(size=(n, gates))),
            "snr": (("ray", "range"), np.full((n, gates), 0.1)),
        },
        coords={
            "time": ("ray", time),
            "azimuth": ("ray", azimuth),
            "elevation": ("ray", elevation),
            "range": ("range", (np.arange(gates) + 0.5) * gate_m),
        },
        attrs={
            "source_files": [name],
            "scan_type": scan_type,
            "system_id": "1",
            "instrument_kind": "streamline",
            "homodyne": 0,
        },
    )


def step_stare(
    rotations: int,
    n_rays: int = 24,
    start: float = 0.0,
    sign: float = 1.0,
    t0: float = 0.0,
    dt: float = 2.0,
    elevation: float = 75.0,
    **kw,
) -> xr.Dataset:
    i = np.arange(rotations * n_rays)
    az = np.mod(start + sign * i * 360.0 / n_rays, 360.0)
    return scan_ds(az, elevation, t0 + dt * i, **kw)


def test_azimuth_steps_wrap() -> None:
    np.testing.assert_allclose(
        azimuth_steps(np.array([350.0, 10.0, 355.0, 0.0])), [20.0, -15.0, 5.0]
    )


def test_step_stare_vad_several_rotations() -> None:
    ds = assign_scans(step_stare(3))
    assert ds["scan"].dtype == np.int64
    np.testing.assert_array_equal(ds["scan"].values, np.repeat([0, 1, 2], 24))


def test_continuous_scan_decreasing_azimuth_with_wrap() -> None:
    i = np.arange(160)
    ds = assign_scans(scan_ds(np.mod(100.0 - 7.0 * i, 360.0), 60.0, 0.5 * i))
    # the ray that has turned 360 deg - step/2 or more opens the next rotation
    expected = np.floor((7.0 * i + 3.5) / 360.0).astype(int)
    np.testing.assert_array_equal(ds["scan"].values, expected)
    counts = np.bincount(ds["scan"].values)
    assert counts[0] == 51 and counts[1] == 52  # 360/7 = 51.4 rays per rotation


def test_closing_ray_with_jitter_opens_next_rotation() -> None:
    az = np.r_[np.arange(0.0, 360.0, 15.0), 359.99, np.arange(15.0, 360.0, 15.0)]
    ds = assign_scans(scan_ds(az, 70.0, np.arange(az.size)))
    np.testing.assert_array_equal(ds["scan"].values, np.repeat([0, 1], 24))


def test_partial_rotation_is_a_scan() -> None:
    ds = assign_scans(scan_ds(np.arange(10) * 15.0, 75.0, np.arange(10)))
    assert (ds["scan"].values == 0).all()


def test_vertical_stare_between_cones() -> None:
    cone1 = step_stare(1)
    stare = scan_ds(np.r_[359.99, 0.0, 0.01] * np.ones(1), [90.01, 90.0, 89.99], 50 + np.arange(3))
    cone2 = step_stare(1, t0=60.0)
    ds = concat_scans([cone1, stare, cone2])
    np.testing.assert_array_equal(ds["scan"].values, np.r_[[0] * 24, [-1] * 3, [1] * 24])


def test_fixed_direction_low_elevation_stare_is_no_scan() -> None:
    rng = np.random.default_rng(3)
    az = 45.0 + rng.uniform(-0.01, 0.01, size=50)  # inclinometer jitter only
    ds = assign_scans(scan_ds(az, 30.0, np.arange(50)))
    assert (ds["scan"].values == -1).all()


def test_stepped_user_scan_with_two_azimuths_per_elevation_is_no_scan() -> None:
    # two rays at one elevation, then the elevation changes (a stepped trajectory)
    az = [0.0, 320.19, 320.19, 140.19, 140.19, 180.0]
    el = [0.0, 0.0, 14.37, 37.53, 0.0, 0.0]
    ds = assign_scans(scan_ds(az, el, np.arange(6), scan_type="S_traj - stepped"))
    assert (ds["scan"].values == -1).all()


def test_cones_at_two_elevations_are_separate_scans() -> None:
    a = step_stare(1, elevation=75.0)
    b = step_stare(1, elevation=35.0, t0=48.0)
    ds = concat_scans([a, b])
    np.testing.assert_array_equal(ds["scan"].values, np.repeat([0, 1], 24))


def test_long_pause_starts_a_new_scan() -> None:
    az = np.arange(12) * 15.0  # half a rotation, pause of 10 min, the other half
    t = np.r_[np.arange(6), 600 + np.arange(6)]
    ds = assign_scans(scan_ds(az, 75.0, t))
    np.testing.assert_array_equal(ds["scan"].values, np.repeat([0, 1], 6))


def test_reversal_of_direction_starts_a_new_sweep() -> None:
    az = np.r_[np.arange(0, 181, 15.0), np.arange(165, -1, -15.0)]  # sector scan back and forth
    ds = assign_scans(scan_ds(az, 70.0, np.arange(az.size)))
    scans = ds["scan"].values
    assert scans[0] == 0 and scans[12] == 0 and scans[13] == 1 and scans[-1] == 1


def test_unsorted_rays_are_segmented_in_time_order() -> None:
    ds = step_stare(2)
    perm = np.random.default_rng(1).permutation(48)
    out = assign_scans(ds.isel(ray=perm))
    np.testing.assert_array_equal(out["scan"].values, np.repeat([0, 1], 24)[perm])


def test_concat_sorts_drops_duplicates_and_records_files() -> None:
    parts = [step_stare(1, t0=48.0 * k, seed=k, name=f"VAD_{k}.hpl") for k in range(3)]
    ds = concat_scans([parts[2], parts[0], parts[1], parts[0]])
    assert ds.sizes["ray"] == 72
    assert np.all(np.diff(ds["time"].values) > np.timedelta64(0, "ns"))
    np.testing.assert_array_equal(ds["scan"].values, np.repeat([0, 1, 2], 24))
    assert ds.attrs["source_files"] == ["VAD_2.hpl", "VAD_0.hpl", "VAD_1.hpl"]
    # data follow their rays
    np.testing.assert_array_equal(
        ds["radial_velocity"].values[:24], parts[0]["radial_velocity"].values
    )


def test_concat_fills_optional_variables_missing_in_some_files() -> None:
    a = step_stare(1, name="a.hpl")
    b = step_stare(1, t0=48.0, name="b.hpl").assign(
        spectral_width=(("ray", "range"), np.ones((24, 5)))
    )
    ds = concat_scans([a, b])
    assert np.isnan(ds["spectral_width"].values[:24]).all()
    assert (ds["spectral_width"].values[24:] == 1).all()


def test_concat_incompatible_range_grids_names_the_files() -> None:
    a = step_stare(1, name="VAD_a.hpl")
    b = step_stare(1, t0=48.0, gate_m=48.0, name="VAD_b.hpl")
    with pytest.raises(CwprocError, match=r"VAD_a\.hpl.*VAD_b\.hpl"):
        concat_scans([a, b])


def test_concat_different_instruments_refused() -> None:
    a = step_stare(1, name="a.hpl")
    b = step_stare(1, t0=48.0, name="b.hpl")
    b.attrs["system_id"] = "2"
    with pytest.raises(CwprocError, match="system_id"):
        concat_scans([a, b])


def test_concat_nothing() -> None:
    with pytest.raises(CwprocError):
        concat_scans([])


def test_real_vad_file_concatenated_with_itself_keeps_two_rays(real_data: Path) -> None:
    ds = read_hpl(real_data / "hpl" / "soverato-2021-10-01-VAD_194_20210624_170110.hpl")
    both = concat_scans([ds, ds])
    assert both.sizes["ray"] == 2
    assert both["scan"].values.tolist() == [0, 0]


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (True, True), (False, False), (1, True), (0, False), (np.int8(1), True),
        (np.array([0], dtype=np.int32), False), (1.0, True),
        ("1", True), ("0", False), ("true", True), ("false", False), (" True ", True),
        ("FALSE", False),
    ],
)  # fmt: skip
def test_parse_homodyne_accepts_bool_int_and_words(value: object, expected: bool) -> None:
    assert parse_homodyne(value) is expected


@pytest.mark.parametrize("value", ["yes", "", "2", 2, 0.5, None, [0, 1], np.array([1, 1])])
def test_parse_homodyne_rejects_everything_else(value: object) -> None:
    with pytest.raises(ValueError, match="expected 0/1, true/false"):
        parse_homodyne(value)


def test_is_homodyne_names_the_files_and_defaults_to_heterodyne() -> None:
    ds = xr.Dataset(attrs={"source_files": ["a.nc"]})
    assert is_homodyne(ds) is False
    ds.attrs["homodyne"] = "false"
    assert is_homodyne(ds) is False  # bool("false") would say True
    ds.attrs["homodyne"] = "on"
    with pytest.raises(CwprocError, match=r"a\.nc.*homodyne is 'on'"):
        is_homodyne(ds)


def _run_pointing(draw_steps, rng: np.random.Generator, n: int):
    """Pointing of ``n`` rays: sweeps that turn either way, stares, elevation changes."""
    azimuth = np.mod(np.cumsum(draw_steps(n)), 360.0)
    elevation = np.where(rng.random(n) < 0.05, 90.0, 75.0)
    elevation = elevation + np.where(rng.random(n) < 0.05, 5.0, 0.0)
    return azimuth, elevation


@given(
    sizes=st.lists(st.integers(0, 40), min_size=1, max_size=8),
    seed=st.integers(0, 2**32 - 1),
    types=st.lists(st.sampled_from(["VAD", "User file 1 - stepped", "Stare", ""]), min_size=8),
)
@settings(max_examples=150, deadline=None)
def test_scan_indices_of_runs_equal_each_run_numbered_alone(sizes, seed, types):
    """The files of a record numbered in one pass (scan_indices_of_runs) exactly as
    each file's own scan_indices numbers it: sweeps that reverse, pause, change
    elevation or stare, and runs of 0 to 40 rays whose scan type sets min_rays."""
    rng = np.random.default_rng(seed)
    n = sum(sizes)

    def steps(k):
        kind = rng.choice(4, size=k)
        return np.choose(
            kind, [np.full(k, 30.0), np.full(k, -45.0), rng.uniform(-180, 180, k), np.full(k, 0.05)]
        )

    azimuth, elevation = _run_pointing(steps, rng, n)
    gaps = np.where(rng.random(n) < 0.05, 200.0, rng.uniform(0.1, 5.0, n))
    time = T0 + np.cumsum(np.round(gaps * 1e9)).astype("timedelta64[ns]")
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    got = scan_indices_of_runs(time, azimuth, elevation, bounds, types[: len(sizes)])
    for k, (a, b) in enumerate(itertools.pairwise(bounds)):
        alone, _ = scan_indices(time[a:b], azimuth[a:b], elevation[a:b], scan_type=types[k])
        np.testing.assert_array_equal(got[k], alone)


def test_scan_indices_of_runs_refuses_times_out_of_order():
    """Runs must be in time order: a step back in time is refused, not misnumbered."""
    time = T0 + np.array([0, 2, 1], dtype="timedelta64[s]")
    with pytest.raises(ValueError, match="strictly increasing"):
        scan_indices_of_runs(time, np.zeros(3), np.zeros(3), [0, 3], ["VAD"])
    with pytest.raises(ValueError, match="bounds"):
        scan_indices_of_runs(time[:2], np.zeros(2), np.zeros(2), [0, 1], ["VAD"])


def test_scan_indices_of_runs_start_a_sweep_at_each_file():
    """A file's first ray starts a sweep even where it would continue the last file's
    (a one-ray file: its time origin then equals the next file's)."""
    time = T0 + np.arange(5).astype("timedelta64[s]")
    azimuth = np.array([0.0, 30.0, 60.0, 90.0, 120.0])
    elevation = np.full(5, 75.0)
    got = scan_indices_of_runs(time, azimuth, elevation, [0, 1, 5], ["VAD", "VAD"])
    np.testing.assert_array_equal(got[0], [-1])
    np.testing.assert_array_equal(got[1], [0, 0, 0, 0])
    alone, _ = scan_indices(time[1:], azimuth[1:], elevation[1:], scan_type="VAD")
    np.testing.assert_array_equal(got[1], alone)
