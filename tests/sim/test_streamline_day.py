"""A long Stream Line series with many gates: the periodic field keeps its statistics.

The frozen field is periodic (``StreamLineSpec.field_shape`` x spacing); a day at 6 m/s
carries it about 500 km, hundreds of box lengths, and 100 gates of 30 m reach far beyond
one box. Stated property: every sampled radial velocity is a probe average of one
stationary, homogeneous field, so the mean wind and the variance of the turbulent part
are the same late in the day as at its start, and at gates beyond the box.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cwproc.physics.geometry import radial_velocity, wind_components
from cwproc.sim.sample_data import StreamLineSpec, simulate_streamline, streamline_field

SPEC = dataclasses.replace(
    StreamLineSpec(),
    n_gates=100,
    gate_length_m=30.0,
    scan_period_s=45.0,
    range_step_m=7.5,
    noise_std=0.0,
    wind_speed=6.0,
    wind_direction_deg=240.0,
)


def _residuals(first_scan: int, n_scans: int, field) -> tuple[np.ndarray, np.ndarray]:
    """Radial velocities less the true mean wind (rays x gates), and the VAD-fit wind."""
    ds = simulate_streamline(SPEC, field=field, first_scan=first_scan, n_scans=n_scans)
    u, v = wind_components(SPEC.wind_speed, SPEC.wind_direction_deg)
    az = ds["azimuth"].values
    vr = ds["radial_velocity"].values
    mean = radial_velocity(u, v, 0.0, az, SPEC.elevation_deg)[:, None]
    el = np.deg2rad(SPEC.elevation_deg)
    design = np.stack(
        [np.sin(np.deg2rad(az)) * np.cos(el), np.cos(np.deg2rad(az)) * np.cos(el)], axis=1
    )
    fit, *_ = np.linalg.lstsq(design, vr - vr.mean(axis=0), rcond=None)
    return vr - mean, fit


@pytest.fixture(scope="module")
def field():
    return streamline_field(SPEC)


def test_day_end_and_far_gates_keep_the_variance_and_the_wind(field):
    n = 8  # scans of 180 rays: 1440 rays a block
    start, _ = _residuals(0, n, field)
    late, fit_late = _residuals(1900, n, field)  # 23.75 h later, 513 km downwind
    u, v = wind_components(SPEC.wind_speed, SPEC.wind_direction_deg)
    near, far = slice(5, 20), slice(80, 100)  # 165-585 m; 2415-2985 m (box: 1280 m)
    var = {
        (t, g): np.var(r[:, s])
        for t, r in (("start", start), ("late", late))
        for g, s in (("near", near), ("far", far))
    }
    # homogeneous and stationary: the same variance late in the day, near and far
    # (sampling error of 8 scans of a field with L_V = 150 m: about 20 %)
    for g in ("near", "far"):
        assert var[("late", g)] == pytest.approx(var[("start", g)], rel=0.25)
    for t in ("start", "late"):
        # the far gates average over wider arcs (85 m at 3 km): less variance, not much
        assert 0.6 < var[(t, "far")] / var[(t, "near")] < 1.0
    # the wind is recovered at the far gates at the end of the day (VAD fit, 0.3 m/s)
    np.testing.assert_allclose(fit_late[:, far].mean(axis=1), [u, v], atol=0.3)
    # and the turbulent part is neither lost nor frozen: several 0.1 m2/s2 at every gate
    assert np.all(np.var(late, axis=0) > 0.05)
