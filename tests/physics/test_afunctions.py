"""A-functions of Smalikho (2020), eqs. 15-23, against analytic limits and reference values.

Reference numbers are copied from ``reference/REFERENCE_VALUES.md`` (independent
computation, accurate to about 1e-5 relative), cited by section and row.
"""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.cli.theory_eps import first_exceedance
from cwproc.physics import spectra
from cwproc.physics.afunctions import (
    a2,
    a_curve_splines,
    a_curves,
    a_par,
    a_perp,
)
from cwproc.physics.epsilon_bias import epsilon_bias_ratio, q1, q2
from cwproc.physics.transfer import CWProbe, PulsedProbe

PRINTED = PulsedProbe(15.3, 18.0, "printed")
PHYSICAL = PulsedProbe(15.3, 18.0, "physical")
MU = np.array([0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0])


@pytest.mark.parametrize("probe", [None, PulsedProbe(0.0, 0.0)], ids=["point", "zero-length"])
def test_no_filter_gives_kolmogorov_laws(probe):
    # Smalikho (2020), eqs. 12-13 with C_K = 2 and the exact constant of eq. 18
    r = np.array([0.3, 3.0, 30.0, 300.0])
    perp, par = a_curves(r, probe=probe, dy=0.0)
    np.testing.assert_allclose(perp, 8 / 3 * r ** (2 / 3), rtol=3e-5)
    np.testing.assert_allclose(par, 2 * r ** (2 / 3), rtol=3e-5)
    np.testing.assert_allclose(par / perp, 0.75, rtol=3e-5)


def test_printed_constant_normalisation():
    # REFERENCE_VALUES.md 1.1: with C = 0.0652, A_perp = 2.66505 r^(2/3), A_par = 1.99879 r^(2/3)
    r = np.array([1.0, 10.0])
    perp, par = a_curves(r, probe=None, dy=0.0, constant=0.0652)
    np.testing.assert_allclose(perp / r ** (2 / 3), 2.66505, rtol=2e-5)
    np.testing.assert_allclose(par / r ** (2 / 3), 1.99879, rtol=2e-5)


# REFERENCE_VALUES.md 1.2 (printed eq. 19, C = 0.0652): (dy, r, A_perp, A_par)
TABLE_1_2 = [
    (3, 3, 1.13042, 0.23362),
    (3, 6, 3.17151, 0.90558),
    (3, 9, 5.32113, 1.93899),
    (3, 12, 7.43791, 3.23114),
    (3, 15, 9.48487, 4.67541),
    (3, 30, 18.65925, 11.85301),
    (3, 60, 33.64765, 23.29629),
    (6, 6, 2.63344, 0.83791),
    (6, 12, 6.85525, 3.01243),
    (6, 18, 10.87146, 5.81603),
    (6, 24, 14.59962, 8.67392),
    (6, 30, 18.08157, 11.36349),
    (6, 60, 33.07692, 22.75746),
    (6, 120, 57.02728, 40.77570),
    (12, 12, 5.48714, 2.60318),
    (12, 24, 13.22136, 7.76213),
    (12, 36, 20.00465, 12.77761),
    (12, 48, 26.11060, 17.33560),
    (12, 60, 31.73807, 21.54538),
    (12, 120, 55.70162, 39.49975),
    (12, 240, 93.77681, 68.04892),
]


@pytest.mark.parametrize("dy", [3, 6, 12])
def test_reference_a_tables(dy):
    rows = [row for row in TABLE_1_2 if row[0] == dy]
    r = np.array([row[1] for row in rows], float)
    perp, par = a_curves(r, probe=PRINTED, dy=float(dy), constant=0.0652)
    np.testing.assert_allclose(perp, [row[2] for row in rows], rtol=1e-4)
    np.testing.assert_allclose(par, [row[3] for row in rows], rtol=1e-4)


# REFERENCE_VALUES.md 1.3.2 / 1.3.3 / 1.3.5 (printed), rows (phi, dy), mu = MU
RATIO_PRINTED = {
    2: {
        (16, 3): [1.0000, 0.9953, 0.9882, 1.0929, 1.5702, 2.3262, 4.2284, 8.1776],
        (45, 6): [1.0000, 1.0019, 1.0117, 1.1665, 1.6741, 2.3291, 3.6465, 6.1455],
        (60, 12): [1.0000, 1.0029, 1.0122, 1.1495, 1.6066, 2.1330, 3.1667, 5.2363],
    },
    3: {
        (16, 12): [1.0000, 0.9951, 0.9812, 1.0160, 1.3865, 1.8250, 2.6918, 4.4364],
        (35.3, 6): [1.0000, 0.9993, 1.0004, 1.1059, 1.5632, 2.1371, 3.2716, 5.4574],
        (60, 3): [1.0000, 1.0132, 1.0567, 1.3122, 1.9347, 2.7377, 4.4784, 7.9299],
    },
    5: {
        (16, 6): [1.0000, 0.9968, 0.9894, 1.0425, 1.4443, 1.9326, 2.9025, 4.8041],
        (45, 3): [1.0000, 1.0050, 1.0236, 1.1842, 1.7023, 2.3658, 3.7548, 6.4823],
        (60, 12): [1.0000, 1.0057, 1.0235, 1.1468, 1.5726, 2.0485, 3.0140, 4.9698],
    },
}


@pytest.mark.parametrize(
    ("lag", "phi", "dy"),
    [(lag, phi, dy) for lag, rows in RATIO_PRINTED.items() for (phi, dy) in rows],
)
def test_reference_ratio_tables_printed(lag, phi, dy):
    ratio = epsilon_bias_ratio(MU, phi, float(dy), lag, probe=PRINTED)
    np.testing.assert_allclose(ratio, RATIO_PRINTED[lag][(phi, dy)], rtol=2e-4)


# REFERENCE_VALUES.md 1.3.pi (Gaussian term with pi), l = 3
RATIO_PI = {
    (16, 3): [1.0000, 0.9983, 0.9996, 1.1184, 1.6081, 2.3923, 4.5068, 9.6475],
    (35.3, 12): [1.0000, 0.9992, 0.9999, 1.1014, 1.5521, 2.1127, 3.2210, 5.3679],
    (45, 6): [1.0000, 1.0059, 1.0279, 1.2137, 1.7693, 2.5165, 4.1487, 7.3475],
    (60, 3): [1.0000, 1.0213, 1.0888, 1.4348, 2.1947, 3.2284, 5.7107, 11.2384],
}


@pytest.mark.parametrize(("phi", "dy"), list(RATIO_PI))
def test_reference_ratio_table_physical(phi, dy):
    ratio = epsilon_bias_ratio(MU, phi, float(dy), 3, probe=PHYSICAL)
    np.testing.assert_allclose(ratio, RATIO_PI[(phi, dy)], rtol=2e-4)


def test_paper_figure_claims_with_physical_transfer_and_lag_3():
    # Smalikho (2020), text after eq. 23; REFERENCE_VALUES.md 1.4 ("pi l=3" column)
    mu = np.linspace(0.3, 1.5, 1201)
    mu_60 = first_exceedance(mu, epsilon_bias_ratio(mu, 60, 3.0, 3, probe=PHYSICAL))
    mu_16 = first_exceedance(mu, epsilon_bias_ratio(mu, 16, 12.0, 3, probe=PHYSICAL))
    at_24 = float(epsilon_bias_ratio(np.array([2.4]), 60, 3.0, 3, probe=PHYSICAL)[0])
    assert mu_60 == pytest.approx(0.529, abs=2e-3)
    assert mu_16 == pytest.approx(1.101, abs=2e-3)
    assert at_24 == pytest.approx(4.173, rel=2e-3)
    # and the paper's rounded figures: 0.55, 1.1, "4 times"
    assert mu_60 == pytest.approx(0.55, rel=0.05)
    assert mu_16 == pytest.approx(1.1, rel=0.01)
    assert at_24 == pytest.approx(4.0, rel=0.05)


def test_q_functions():
    # Smalikho (2020): for mu = 3, phi = 45 deg eqs. 22-23 give 2.7 and 10
    assert float(q1(45) * 3) == pytest.approx(2.7232, abs=1e-4)
    assert float(q2(45) * 3**2.5) == pytest.approx(10.1250, abs=1e-4)
    # at phi = 90 deg the radial velocity is vertical: no anisotropy factor
    assert float(q1(90)) == pytest.approx(1.0)
    assert float(q2(90)) == pytest.approx(1.0)


def test_asymptote_eq22_large_lags():
    # REFERENCE_VALUES.md 1.4: l = 10, dy = 100 m (l dy >> dz): ratio/(q1 mu) = 0.9939, 0.9923
    mu = np.array([10.0, 30.0])
    ratio = epsilon_bias_ratio(mu, 45, 100.0, 10, probe=PRINTED) / (q1(45) * mu)
    np.testing.assert_allclose(ratio, [0.9939, 0.9923], atol=2e-4)
    assert np.all(np.abs(ratio - 1) < 0.01)


def test_asymptote_eq23_small_lags():
    # REFERENCE_VALUES.md 1.4: l = 2, dy = 0.01 m (l dy mu << dz): ratio/(q2 mu^2.5) at mu = 3
    ratio = epsilon_bias_ratio(np.array([3.0]), 45, 0.01, 2, probe=PRINTED) / (q2(45) * 3.0**2.5)
    assert float(ratio[0]) == pytest.approx(1.0907, abs=5e-4)


def test_a2_reduces_to_a_perp_without_wind():
    dy = 4.0
    lags = np.array([1, 2, 5])
    np.testing.assert_allclose(
        a2(lags, dy, 0.0, 60.0, probe=PHYSICAL), a_perp(lags * dy, probe=PHYSICAL, dy=dy), rtol=1e-5
    )


def test_a2_pure_wind_transport_limit():
    # mu -> infinity: the lag l dy sqrt(g) tends to l dy mu for every azimuth; at
    # phi = 90 deg the radial velocity is vertical and only A_perp counts (eq. 15)
    dy, mu = 1.0, 50.0
    val = a2(np.array([2]), dy, mu, 89.999, probe=None)
    expected = a_perp(2 * dy * mu, probe=None, dy=dy)
    assert float(val[0]) == pytest.approx(float(expected), rel=1e-3)
    # with an unfiltered point probe it is the Kolmogorov law (8/3) (l dy mu)^(2/3)
    val0 = a2(np.array([2]), 1e-6, mu * 1e6, 89.999, probe=None)
    assert float(val0[0]) == pytest.approx(8 / 3 * (2 * dy * mu) ** (2 / 3), rel=1e-3)


@pytest.mark.parametrize("model", ["von_karman", "exponential"])
def test_finite_outer_scale_unfiltered_matches_closed_form(model):
    big_l = 100.0
    r = np.array([0.5, 5.0, 50.0, 500.0])
    perp, par = a_curves(r, probe=None, dy=0.0, model=model, outer_scale_m=big_l)
    np.testing.assert_allclose(
        perp, spectra.transverse_structure_function(r, model, big_l), rtol=5e-5
    )
    np.testing.assert_allclose(
        par, spectra.longitudinal_structure_function(r, model, big_l), rtol=5e-5
    )


@pytest.mark.parametrize("model", ["von_karman", "exponential"])
def test_finite_outer_scale_tends_to_inertial(model):
    r = np.array([6.0, 30.0])
    inertial = a_perp(r, probe=PHYSICAL, dy=3.0)
    devs = []
    for big_l in (1e3, 1e5, 1e7):
        finite = a_perp(r, probe=PHYSICAL, dy=3.0, model=model, outer_scale_m=big_l)
        # an outer scale removes large-scale energy (to within the 1e-6 quadrature noise)
        assert np.all(finite < inertial * (1 + 1e-6))
        devs.append(np.max(np.abs(finite / inertial - 1)))
    assert devs[0] > devs[1] > devs[2]
    assert devs[0] > 1e-3  # L_V = 1 km is visible at these lags
    # von Karman deviates as (r/L)^(4/3), the exponential model as (r/L)^(2/3)
    assert devs[2] < 5e-4


@pytest.mark.parametrize("model", ["von_karman", "exponential"])
def test_finite_outer_scale_saturates(model):
    big_l = 50.0
    sat = 2 * spectra.variance_per_eps23(model, big_l)
    far = np.array([5e4])
    # both tend to twice the variance left after the probe-volume averaging; the variance
    # lost in a probe of size s is the inertial-range part ~ s^(2/3): 10^(2/3) per decade
    shortfall = []
    for probe, dy in (
        (PHYSICAL, 3.0),
        (PulsedProbe(1.0, 1.0), 0.3),
        (PulsedProbe(0.1, 0.1), 0.03),
        (PulsedProbe(0.01, 0.01), 0.003),
    ):
        perp, par = a_curves(far, probe=probe, dy=dy, model=model, outer_scale_m=big_l)
        assert float(perp[0]) == pytest.approx(float(par[0]), rel=1e-6)
        assert float(perp[0]) < sat
        shortfall.append(1 - float(perp[0]) / sat)
    assert shortfall[0] > shortfall[1] > shortfall[2] > shortfall[3]
    assert shortfall[2] / shortfall[3] == pytest.approx(10 ** (2 / 3), rel=0.03)


def test_cw_probe_filters_more_at_larger_range():
    probe = CWProbe(0.0013)
    r = np.array([10.0])
    values = [float(a_perp(r, probe=probe, dy=2.0, range_m=rng)[0]) for rng in (20, 100, 300)]
    assert values[0] > values[1] > values[2]
    # a tiny Z_R is no filter at all: same as the point probe
    tiny = float(a_perp(r, probe=probe, dy=2.0, range_m=0.5)[0])
    point = float(a_perp(r, probe=None, dy=2.0)[0])
    assert tiny == pytest.approx(point, rel=2e-3)


def test_spline_curves_match_direct_values():
    curves = a_curve_splines(0.05, 200.0, probe=PHYSICAL, dy=3.0)
    r = np.array([0.37, 4.1, 17.3, 151.0])
    perp, par = a_curves(r, probe=PHYSICAL, dy=3.0)
    np.testing.assert_allclose(curves.perp(r), perp, rtol=1e-6)
    np.testing.assert_allclose(curves.par(r), par, rtol=1e-6)


def test_bad_arguments():
    with pytest.raises(ValueError, match="lag_number"):
        epsilon_bias_ratio(MU, 60, 3.0, 1, probe=PHYSICAL)
    with pytest.raises(ValueError, match="range_m"):
        a_perp(3.0, probe=CWProbe(), dy=1.0)
    with pytest.raises(ValueError, match="outer scale"):
        a_par(3.0, probe=PHYSICAL, dy=1.0, model="von_karman")
    with pytest.raises(ValueError, match="dy"):
        a_perp(3.0, probe=PHYSICAL, dy=-1.0)


def test_inertial_a_functions_bias_cw_epsilon_low():
    # REFERENCE_VALUES.md section 3: for the cw lidar of Banakh et al. (1999) (10.6 um,
    # a0 = 7.5 cm, phi = 30 deg, dtheta = 360 deg * 50 ms / 7 s) fitting D_L made with the
    # eq. 17 model by the inertial-range A-functions biases eps low by 28 % at 50 m and
    # 68 % at 500 m (their least-squares estimator; here eq. 5 with l = 3, noise free)
    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    dtheta = np.radians(360 * 0.05 / 7)
    ratios = []
    for h, big_l in ((50.0, 133.0), (500.0, 333.0)):
        rng = h / np.sin(np.radians(30))
        dy = dtheta * h / np.tan(np.radians(30))
        lags = np.array([1.0, 3.0]) * dy
        true_a = a_perp(
            lags, probe=probe, dy=dy, range_m=rng, model="exponential", outer_scale_m=big_l
        )
        inertial_a = a_perp(lags, probe=probe, dy=dy, range_m=rng)
        ratios.append(((true_a[1] - true_a[0]) / (inertial_a[1] - inertial_a[0])) ** 1.5)
    assert 0.6 < ratios[0] < 0.8  # 20-40 % low at 50 m
    assert 0.2 < ratios[1] < 0.4  # 60-80 % low at 500 m: "up to a factor 3"


def test_filon_moments_match_scipy_spherical_bessel():
    # the quadrature moments need j_0..j_7 everywhere, including the zeros of j_0 (x = n pi)
    from scipy import special

    from cwproc.physics.afunction_quadrature import spherical_j

    x = np.concatenate(
        [[0.0, 1e-9], np.geomspace(1e-4, 1e5, 4000), np.pi * np.arange(1, 6), [4.4934094579]]
    )
    ours = spherical_j(x, 8)
    ref = np.array([special.spherical_jn(m, x) for m in range(8)])
    assert np.max(np.abs(ours - ref) / np.abs(ref).max(axis=0)) < 1e-12


def test_shared_plane_matrix_gives_identical_results():
    from cwproc.physics.afunction_quadrature import PlaneMatrix
    from cwproc.physics.afunctions import panel_limits

    r = np.array([2.0, 7.5, 40.0])
    lo, hi, _ = panel_limits(0.01, 500.0, probe=PHYSICAL, dy=1.0)
    plane = PlaneMatrix(lo / 10, hi * 10, "von_karman", 80.0)
    direct = a_curves(r, probe=PHYSICAL, dy=2.5, model="von_karman", outer_scale_m=80.0)
    shared = a_curves(
        r, probe=PHYSICAL, dy=2.5, model="von_karman", outer_scale_m=80.0, plane=plane
    )
    np.testing.assert_allclose(shared, direct, rtol=1e-12)
