"""Despiking, rotation, error laws and the Foken & Wichura (1996) tests of one window.

Series are Gaussian AR(1) processes (exact statistics known) with spikes, steps and
trends injected where the test says.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from cwproc.physics import dissipation
from cwproc.physics import sonic_turbulence as st

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sonic_series import RATE, N, ar1, with_spikes


@pytest.mark.parametrize("method", ["vickers_mahrt", "mauder"])
def test_despiking_finds_every_injected_spike_and_spares_the_burst(method):
    rng = np.random.default_rng(3)
    x = ar1(N, 0.9, rng)
    y, truth = with_spikes(x, rng)
    if method == "vickers_mahrt":
        clean, spikes = st.despike_vickers_mahrt(y, RATE)
    else:
        clean, spikes = st.despike_mauder(y)
    assert spikes[truth].all()
    assert not spikes[9000:9020].any()
    # false alarms on the Gaussian samples: VM97's 3.5 sigma passes about 5e-4 of them
    # (two-sided normal tail); Mauder's 7 MAD/0.6745 none
    false = spikes & ~truth
    assert false.mean() <= (1e-3 if method == "vickers_mahrt" else 0.0)
    # the variance of the clean series is restored within 1 % (burst excluded)
    keep = np.ones(N, dtype=bool)
    keep[8990:9030] = False
    assert np.var(clean[keep]) == pytest.approx(np.var(x[keep]), rel=0.01)
    assert np.var(y[keep]) > 1.2 * np.var(x[keep])  # the spikes mattered


def test_double_rotation_recovers_a_known_tilt():
    rng = np.random.default_rng(1)
    u2 = 5.0 + ar1(N, 0.9, rng, 0.8)
    v2 = ar1(N, 0.9, rng, 0.6)
    w2 = ar1(N, 0.9, rng, 0.4)
    yaw, pitch = np.radians(35.0), np.radians(4.0)
    # streamline -> instrument: undo the pitch, then the yaw
    u1 = u2 * np.cos(pitch) - w2 * np.sin(pitch)
    w = u2 * np.sin(pitch) + w2 * np.cos(pitch)
    u = u1 * np.cos(yaw) - v2 * np.sin(yaw)
    v = u1 * np.sin(yaw) + v2 * np.cos(yaw)
    ur, vr, wr, g, a = st.double_rotation(u, v, w)
    assert abs(np.mean(vr)) < 1e-12 and abs(np.mean(wr)) < 1e-12
    assert np.mean(ur) == pytest.approx(
        np.sqrt(np.mean(u) ** 2 + np.mean(v) ** 2 + np.mean(w) ** 2)
    )
    # the means of v2, w2 are not exactly zero, so the angles differ by their ratio to U
    assert g == pytest.approx(35.0 + np.degrees(np.mean(v2) / 5.0), abs=0.05)
    assert a == pytest.approx(4.0 + np.degrees(np.mean(w2) / 5.0), abs=0.05)
    assert np.var(wr) == pytest.approx(np.var(w2), rel=0.02)


def test_integral_time_scale_and_variance_error_of_an_ar1_process():
    """AR(1): T = dt (1/(1 - phi) - 1/2) and the sample variance's scatter
    var sqrt(2 T / T_avg) (Lenschow et al. (1994)), over 200 realisations."""
    rng = np.random.default_rng(7)
    phi, n = 0.95, 6000
    t_true = (1 / (1 - phi) - 0.5) / RATE
    scales, variances, stated = [], [], []
    for _ in range(200):
        x = ar1(n, phi, rng)
        x = x - x.mean()
        t = st.integral_time_scale(x, RATE)
        scales.append(t)
        variances.append(np.var(x))
        stated.append(st.variance_random_error(np.var(x), t, n / RATE))
    assert np.mean(scales) == pytest.approx(t_true, rel=0.1)
    assert np.mean(stated) == pytest.approx(np.std(variances, ddof=1), rel=0.2)


def test_stationarity_deviation_of_a_trend_in_the_means_is_the_predicted_one():
    """A ramp in both means adds c_t = a b var(ramp) to the window's covariance and
    c_t/36 to each of the 6 sub-windows': RN = |c_t 35/36| / |c_0 + c_t| (Foken &
    Wichura (1996)); without the ramp the flux is steady (RN well under 30 %)."""
    rng = np.random.default_rng(11)
    w = ar1(N, 0.8, rng, 0.4)
    u = -0.8 * w + ar1(N, 0.8, rng, 0.5)
    c0 = np.mean((u - u.mean()) * (w - w.mean()))
    assert st.stationarity_deviation(u, w) < 30.0
    ramp = np.linspace(-1.0, 1.0, N)
    for a, b in ((1.5, -0.3), (1.5, 0.6)):
        c_t = a * b * np.var(ramp)
        predicted = 100 * abs(c_t * 35 / 36) / abs(c0 + c_t)
        rn = st.stationarity_deviation(u + a * ramp, w + b * ramp)
        assert rn == pytest.approx(predicted, rel=0.15)
        assert rn > 30.0
    assert rn > 100.0  # the opposite-signed trend outweighs the flux: flag 2


@pytest.mark.parametrize(
    ("rn", "itc", "flag"),
    [
        (10, 20, 0),
        (30, 30, 0),
        (31, 10, 1),
        (10, 100, 1),
        (101, 10, 2),
        (10, 150, 2),
        (10, np.nan, 0),
        (np.nan, 10, 2),
    ],
)
def test_the_0_1_2_flag_of_mauder_and_foken(rn, itc, flag):
    assert st.foken_flag(rn, itc) == flag


def test_itc_models():
    """Foken et al. (2004) / TK3: 2.0 |z/L|^(1/8) and 4.15 |z/L|^(1/8) unstable;
    0.21 ln(z+ f/u*) + 3.1 and 0.44 ln(z+ f/u*) + 6.3 near neutral (Thomas & Foken
    (2002)); no model beyond (-3, 0.4)."""
    assert st.itc_model_sigma_w(-1.0, 10.0, 52.0, 0.3) == pytest.approx(2.0)
    assert st.itc_model_sigma_w(-2.56, 10.0, 52.0, 0.3) == pytest.approx(2.0 * 2.56**0.125)
    assert st.itc_model_sigma_u(-1.0, 52.0, 0.3) == pytest.approx(4.15)
    f = 2 * 7.2921e-5 * np.sin(np.radians(52.0))
    assert st.itc_model_sigma_w(0.0, 10.0, 52.0, 0.3) == pytest.approx(0.21 * np.log(f / 0.3) + 3.1)
    assert st.itc_model_sigma_u(0.1, 52.0, 0.3) == pytest.approx(0.44 * np.log(f / 0.3) + 6.3)
    assert np.isnan(st.itc_model_sigma_w(1.0, 10.0, 52.0, 0.3))  # stable: no model
    assert np.isnan(st.itc_model_sigma_u(-4.0, 52.0, 0.3))


def test_inertial_lags_take_the_longest_run_near_two_thirds():
    slope = np.array([0.9, 0.7, 0.65, 0.6, 0.3, 0.66, 0.67, 0.7, 0.72, 0.6, np.nan])
    np.testing.assert_array_equal(
        np.flatnonzero(st.inertial_lags(slope, tolerance=0.1, min_points=3)), [5, 6, 7, 8, 9]
    )
    assert not st.inertial_lags(slope, tolerance=0.1, min_points=6).any()


def test_epsilon_of_an_exact_power_law():
    r = np.linspace(0.5, 20, 40)
    eps = 0.01
    d = st.C2_LONGITUDINAL * eps ** (2 / 3) * r ** (2 / 3)
    assert dissipation.epsilon23_from_sf(r, d, st.C2_LONGITUDINAL) ** 1.5 == pytest.approx(eps)


def test_planar_fit_recovers_the_tilt_of_the_instrument():
    """Windows of streamline-flat flow (mean w = 0 in the true frame) from 12 directions
    and speeds, seen by a sonic tilted by 3 deg pitch and 2 deg roll with a w offset of
    0.05 m/s: the fitted normal is the tilted z axis and the rotated mean w vanishes."""
    rng = np.random.default_rng(5)
    pitch, roll = np.radians(3.0), np.radians(2.0)
    ry = np.array(
        [[np.cos(pitch), 0, np.sin(pitch)], [0, 1, 0], [-np.sin(pitch), 0, np.cos(pitch)]]
    )
    rx = np.array([[1, 0, 0], [0, np.cos(roll), -np.sin(roll)], [0, np.sin(roll), np.cos(roll)]])
    to_instrument = (ry @ rx).T  # true frame -> instrument frame
    means, windows = [], []
    for k in range(12):
        d = np.radians(30.0 * k)
        speed = 2.0 + 0.5 * k
        true = np.stack(
            [
                speed * np.cos(d) + ar1(3000, 0.9, rng, 0.5),
                speed * np.sin(d) + ar1(3000, 0.9, rng, 0.5),
                ar1(3000, 0.9, rng, 0.3),
            ]
        )
        true[2] -= true[2].mean()
        inst = to_instrument @ true
        inst[2] += 0.05
        windows.append((inst, true))
        means.append(inst.mean(axis=1))
    means = np.array(means)
    normal, offset = st.planar_fit(means[:, 0], means[:, 1], means[:, 2])
    np.testing.assert_allclose(normal, to_instrument[:, 2], atol=1e-6)
    assert offset == pytest.approx(0.05, abs=1e-6)
    for inst, true in windows:
        u2, v2, w2, _, tilt = st.planar_fit_rotation(*inst, normal, offset)
        assert abs(np.mean(w2)) < 1e-6 and abs(np.mean(v2)) < 1e-9
        assert np.mean(u2) == pytest.approx(np.hypot(true[0].mean(), true[1].mean()))
        assert np.var(w2) == pytest.approx(np.var(true[2]), rel=1e-6)
        assert tilt == pytest.approx(np.degrees(np.arccos(np.cos(pitch) * np.cos(roll))), abs=1e-4)
