"""DBS variance ratios: exact limits of the isotropic model, noise propagation."""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics import dbs

TIMES = {"0": 0.0, "90": 0.8, "180": 1.6, "270": 2.4, "V": 3.2}
STILL = np.zeros(3)


def _ratio(coef, height, scale, nodes=None, wind=STILL, angle=28.0):
    return dbs.estimator_variance_ratio(
        coef,
        height_m=height,
        scan_angle_deg=angle,
        beam_time_s=TIMES,
        mean_wind=wind,
        integral_scale_m=scale,
        range_nodes=nodes,
    )


def test_coincident_point_beams_estimate_the_component_exactly():
    """Beams meeting in one point (h = 0), no wind: u_est = u, var ratio 1."""
    for comp in ("u", "v", "w"):
        coef = dbs.estimator_coefficients(comp, 28.0)
        assert _ratio(coef, 0.0, 100.0) == pytest.approx(1.0, abs=1e-12)
        # 1 mm apart: the (r / L_V)^(2/3) law of the structure function, 1e-5 off
        assert _ratio(coef, 1e-3, 100.0) == pytest.approx(1.0, abs=1e-3)


def test_distant_beams_give_the_uncorrelated_limit():
    """Beams far apart (h >> L_V): var(u_est) = (sin^2 sigma^2 + cos^2 sigma^2) x 2 /
    (4 sin^2 theta) = sigma^2 / (2 sin^2 theta) in isotropic turbulence."""
    theta = np.radians(28.0)
    coef = dbs.estimator_coefficients("u", 28.0)
    assert _ratio(coef, 1e5, 10.0) == pytest.approx(1 / (2 * np.sin(theta) ** 2), rel=1e-3)


def test_cross_contamination_grows_with_height_and_volume_averaging_lowers_variance():
    coef = dbs.estimator_coefficients("u", 28.0)
    ratios = [_ratio(coef, h, 100.0) for h in (20.0, 60.0, 120.0, 200.0)]
    assert np.all(np.diff(ratios) > 0) and ratios[0] > 1.0
    nodes = dbs.range_nodes(15.0, 20.0, 2.5)
    volume = _ratio({"V": 1.0}, 100.0, 100.0, nodes)
    assert 0.0 < volume < 1.0
    # a longer probe averages more; a larger integral scale less
    assert _ratio({"V": 1.0}, 100.0, 100.0, dbs.range_nodes(30.0, 40.0, 2.5)) < volume
    assert _ratio({"V": 1.0}, 100.0, 400.0, nodes) > volume


def test_volume_ratio_is_the_same_for_every_beam_direction():
    """Isotropy: the probe-averaged radial variance does not depend on the beam."""
    nodes = dbs.range_nodes(15.0, 20.0, 2.5)
    values = [_ratio({b: 1.0}, 100.0, 80.0, nodes) for b in ("0", "90", "180", "270", "V")]
    np.testing.assert_allclose(values, values[0], rtol=1e-9)


def test_along_wind_coefficients_rotate_the_dbs_estimates():
    coef = dbs.along_wind_coefficients(3.0, 4.0, 28.0)
    s = np.sin(np.radians(28.0))
    assert coef["90"] == pytest.approx(0.6 * 0.5 / s) and coef["0"] == pytest.approx(0.8 * 0.5 / s)
    # radial velocities of a uniform wind (3, 4, 0): the estimate is its speed, 5
    vr = {b: float(dbs.dbs_beam_unit_vector(b, 28.0) @ np.array([3.0, 4.0, 0.0])) for b in coef}
    assert sum(a * vr[b] for b, a in coef.items()) == pytest.approx(5.0)


def test_noise_variance_of_an_estimate():
    """sum a_k^2 sigma_k^2: u from two beams of noise 0.1 m/s at 28 deg."""
    coef = dbs.estimator_coefficients("u", 28.0)
    var = dbs.noise_variance(coef, {"90": 0.01, "270": 0.01})
    assert var == pytest.approx(0.02 / (4 * np.sin(np.radians(28.0)) ** 2))


def test_range_nodes_are_the_virtual_instruments_weighting():
    """The quadrature of the correction is the range weighting the simulator samples with."""
    from cwproc.sim.pulsed import range_quadrature

    nodes, weights = dbs.range_nodes(15.0, 20.0, 2.5)
    ref_nodes, ref_weights = range_quadrature(15.0, 20.0, 2.5)
    np.testing.assert_allclose(nodes, ref_nodes)
    np.testing.assert_allclose(weights, ref_weights, rtol=1e-12)
