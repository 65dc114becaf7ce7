"""Geometry of conical scanning (Smalikho (2020), eqs. 3, 6-8)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cwproc.physics import geometry as g

angles = st.floats(-720.0, 720.0, allow_nan=False)
elevations = st.floats(-89.0, 179.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(azimuth=angles, elevation=elevations)
def test_beam_unit_vector_has_unit_length(azimuth: float, elevation: float) -> None:
    assert np.linalg.norm(g.beam_unit_vector(azimuth, elevation)) == pytest.approx(1.0, 1e-12)


def test_beam_unit_vector_cardinal_directions() -> None:
    # (east, north, up): north at the horizon, east at the horizon, zenith
    np.testing.assert_allclose(g.beam_unit_vector(0.0, 0.0), [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(g.beam_unit_vector(90.0, 0.0), [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(g.beam_unit_vector(123.0, 90.0), [0, 0, 1], atol=1e-15)
    assert g.beam_unit_vector(np.zeros((4, 5)), 30.0).shape == (4, 5, 3)


@settings(max_examples=200, deadline=None)
@given(u=st.floats(-40, 40), v=st.floats(-40, 40), w=st.floats(-5, 5), az=angles, el=elevations)
def test_radial_velocity_is_projection_on_beam(
    u: float, v: float, w: float, az: float, el: float
) -> None:
    # Smalikho (2020), eq. 8: V_r = S . V
    expected = g.beam_unit_vector(az, el) @ np.array([u, v, w])
    assert g.radial_velocity(u, v, w, az, el) == pytest.approx(expected, abs=1e-9)


def test_wind_from_north_seen_by_north_beam_is_negative() -> None:
    # a northerly wind (v < 0) blows towards a north-pointing beam: V_r < 0
    assert g.radial_velocity(0.0, -10.0, 0.0, 0.0, 0.0) == pytest.approx(-10.0)
    assert g.radial_velocity(0.0, 0.0, 2.0, 77.0, 90.0) == pytest.approx(2.0)


@settings(max_examples=200, deadline=None)
@given(az=st.floats(0.0, 360.0), el=st.floats(-89.0, 179.0))
def test_normalise_pointing_keeps_direction(az: float, el: float) -> None:
    az2, el2 = g.normalise_pointing(az, el)
    assert -90.0 <= el2 <= 90.0
    assert 0.0 <= az2 < 360.0
    np.testing.assert_allclose(g.beam_unit_vector(az2, el2), g.beam_unit_vector(az, el), atol=1e-12)


def test_pointing_normalisation_of_halo_angles() -> None:
    """Over-the-zenith rays (``180.01``) and signed zeros as a Halo scanner writes them."""
    az, el = g.normalise_pointing(
        np.array([360.0, 0.0, 39.81, 320.19, 90.0, 10.0]),
        np.array([75.0, -0.0, 180.01, 142.47, 90.0, 90.01]),
    )
    np.testing.assert_allclose(az, [0.0, 0.0, 219.81, 140.19, 90.0, 190.0], atol=1e-9)
    np.testing.assert_allclose(el, [75.0, 0.0, -0.01, 37.53, 90.0, 89.99], atol=1e-9)
    assert not np.signbit(el[1]) and not np.signbit(az[0])
    assert ((az >= 0) & (az < 360)).all()


@pytest.mark.parametrize(
    ("az", "el", "expected_az", "expected_el"),
    [
        (-0.0, 35.0, 0.0, 35.0),  # -0.00 in a file: azimuth 0, not 360 and not -0
        (-1e-17, 35.0, 0.0, 35.0),  # -1e-17 mod 360 rounds to 360.0: must be 0
        (360.0, -0.0, 0.0, 0.0),
        (-0.0, 180.0, 180.0, 0.0),  # over the zenith to the horizon: el +0
        (180.0, 180.0, 0.0, 0.0),
    ],
)
def test_signed_zero_and_360_become_zero(
    az: float, el: float, expected_az: float, expected_el: float
) -> None:
    az2, el2 = g.normalise_pointing(az, el)
    assert float(az2) == expected_az and not np.signbit(az2)
    assert float(el2) == expected_el and not np.signbit(el2)


def test_heights_radius_speed_sampling() -> None:
    # phi = 30 deg, R = 1000 m: h = 500 m, R' = 866.03 m
    h = g.height_from_range(1000.0, 30.0)
    assert h == pytest.approx(500.0, rel=1e-12)
    radius = g.scan_circle_radius(h, 30.0)
    assert radius == pytest.approx(1000.0 * np.cos(np.deg2rad(30.0)), rel=1e-12)
    # Smalikho (2020), eq. 3: V_s = 2 pi h / (T tan phi); T = 60 s
    assert g.linear_scan_speed(h, 30.0, 60.0) == pytest.approx(2 * np.pi * 866.0254 / 60, 1e-6)
    # dy = dtheta R': 1 deg at R' = 100 m -> 1.74533 m; a full turn -> circumference
    assert g.transverse_sampling(1.0, 100.0) == pytest.approx(1.745329, rel=1e-6)
    assert g.transverse_sampling(360.0, radius) == pytest.approx(2 * np.pi * radius)


def test_functions_broadcast() -> None:
    h = g.height_from_range(np.array([100.0, 200.0])[:, None], np.array([15.0, 45.0, 75.0]))
    assert h.shape == (2, 3)
    np.testing.assert_allclose(
        g.scan_circle_radius(h, [15.0, 45.0, 75.0]),
        np.array([100.0, 200.0])[:, None] * np.cos(np.deg2rad([15.0, 45.0, 75.0])),
    )


def test_wind_components_of_cardinal_directions() -> None:
    """A wind *from* 270 deg (west) blows east, from 180 deg (south) blows north."""
    u, v = g.wind_components(np.array([10.0, 10.0, 10.0, 10.0]), [270.0, 180.0, 90.0, 0.0])
    np.testing.assert_allclose(u, [10.0, 0.0, -10.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(v, [0.0, 10.0, 0.0, -10.0], atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(speed=st.floats(1e-3, 60.0), direction=st.floats(0.0, 359.999))
def test_speed_and_direction_inverts_wind_components(speed: float, direction: float) -> None:
    back_speed, back_direction = g.speed_and_direction(*g.wind_components(speed, direction))
    assert back_speed == pytest.approx(speed, rel=1e-12)
    assert 0.0 <= back_direction < 360.0
    gap = (back_direction - direction + 180.0) % 360.0 - 180.0
    assert abs(gap) < 1e-9


def test_other_component_orders_project_the_same_wind() -> None:
    """The (v, u, w) design matrix of the VAD error theory and the (up, north, east) beams
    of Banakh et al. (1999), eq. 1, give the radial velocity of Smalikho (2020), eq. 8."""
    from cwproc.physics.correlation import wind_vector
    from cwproc.physics.geometry import beam_unit_vector_une
    from cwproc.physics.vad_errors import design_matrix

    azimuth = np.linspace(0.0, 350.0, 36)
    u, v = g.wind_components(7.5, 212.0)
    w = 0.4
    expected = g.radial_velocity(u, v, w, azimuth, 35.3)
    np.testing.assert_allclose(design_matrix(azimuth, 35.3) @ [v, u, w], expected, atol=1e-12)
    np.testing.assert_allclose(
        beam_unit_vector_une(azimuth, 35.3) @ wind_vector(7.5, 212.0, w),
        expected,
        atol=1e-12,
    )
