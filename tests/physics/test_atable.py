"""A-function tables (cwproc.physics.atable) and their store (cwproc.tables.atable):
interpolation accuracy, cache reuse and corrupt-cache rebuilds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cwproc.physics import atable
from cwproc.physics.afunctions import a2, a_perp
from cwproc.physics.atable_interp import ATable, azimuth_bin_weights
from cwproc.physics.transfer import CWProbe, PulsedProbe
from cwproc.tables import atable as stored
from cwproc.tables.atable import get_a_table

PROBE = PulsedProbe()
PHI, DTHETA = 60.0, 3.6
SMALL = {
    "phi_deg": PHI,
    "delta_theta_deg": DTHETA,
    "n_lags": 4,
    "height_range_m": (50.0, 200.0),
    "geometry": "small_angle",
}


def _dy(h: float, phi: float = PHI, dtheta: float = DTHETA) -> float:
    return math.radians(dtheta) * h / math.tan(math.radians(phi))


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("atable-cache")


@pytest.fixture(scope="module")
def table(cache):
    return get_a_table(PROBE, cache_dir=cache, mu_max=3.0, **SMALL)


def test_interpolation_matches_direct_evaluation(table):
    # points between the nodes of every axis; stated interpolation error: 1e-4
    worst = 0.0
    for h in (57.3, 123.4, 188.0):
        dy = _dy(h)
        mus = np.array([0.07, 0.93, 1.01, 2.37, 2.96])
        for lag in (1, 2, 4):
            a1_tab, a2_tab = table.evaluate(lag, h, mus)
            direct2 = a2(lag, dy, mus, PHI, probe=PROBE)
            direct1 = a_perp(lag * dy, probe=PROBE, dy=dy)
            worst = max(worst, np.max(np.abs(a2_tab / direct2 - 1)))
            worst = max(worst, np.max(np.abs(a1_tab / direct1 - 1)))
    assert worst < 1e-4


def test_evaluate_broadcasts_and_flags_outside(table):
    lags = np.arange(1, 5)[:, None, None]
    heights = np.array([60.0, 150.0])[None, :, None]
    mus = np.array([0.0, 0.5, 1.5])[None, None, :]
    a1_v, a2_v = table.evaluate(lags, heights, mus)
    assert a1_v.shape == a2_v.shape == (4, 2, 3)
    np.testing.assert_allclose(a2_v[..., 0], a1_v[..., 0], rtol=1e-9)  # mu = 0: A_2 = A_1
    assert np.all(np.diff(a1_v, axis=0) > 0)  # A grows with the lag
    outside_a1, outside_a2 = table.evaluate(
        np.array([0, 5, 2, 2]),
        np.array([100.0, 100.0, 20.0, 100.0]),
        np.array([1.0, 1.0, 1.0, 3.5]),
    )
    assert np.isnan(outside_a1[:3]).all() and np.isfinite(outside_a1[3])
    assert np.isnan(outside_a2).all()


def test_second_call_reads_the_cache(cache, table, monkeypatch):
    def no_build(*args, **kwargs):
        raise AssertionError("table rebuilt although cached")

    monkeypatch.setattr(stored, "build_a_table", no_build)
    again = get_a_table(PROBE, cache_dir=cache, mu_max=3.0, **SMALL)
    np.testing.assert_array_equal(again.log_a2, table.log_a2)
    assert not list(cache.glob("*.part")), "temporary files left behind"


@pytest.mark.parametrize("damage", ["garbage", "truncated", "nan"])
def test_damaged_cache_is_rebuilt(tmp_path, damage, monkeypatch):
    params = {**SMALL, "height_range_m": (80.0, 110.0), "n_lags": 2}
    first = get_a_table(PROBE, cache_dir=tmp_path, mu_max=1.0, **params)
    (path,) = tmp_path.glob("atable-*.npz")
    if damage == "garbage":
        path.write_bytes(b"not a table at all")
    elif damage == "truncated":
        path.write_bytes(path.read_bytes()[:300])
    else:
        with np.load(path) as data:
            arrays = dict(data)
        arrays["log_a2"] = np.full_like(arrays["log_a2"], np.nan)
        np.savez(path, **arrays)
    calls = []
    real_build = stored.build_a_table

    def counting_build(*args, **kwargs):
        calls.append(1)
        return real_build(*args, **kwargs)

    monkeypatch.setattr(stored, "build_a_table", counting_build)
    second = get_a_table(PROBE, cache_dir=tmp_path, mu_max=1.0, **params)
    assert calls == [1]
    np.testing.assert_allclose(second.log_a2, first.log_a2, rtol=0, atol=0)
    # and the rebuilt file is valid again
    monkeypatch.setattr(stored, "build_a_table", real_build)
    assert stored._load(path, atable.table_key(second.params), second.params) is not None


def test_cache_key_depends_on_every_parameter():
    base = atable.table_parameters(PROBE, **SMALL)
    keys = {
        atable.table_key(base),
        atable.table_key(atable.table_parameters(PulsedProbe(gaussian="printed"), **SMALL)),
        atable.table_key(atable.table_parameters(PROBE, **{**SMALL, "phi_deg": 75.0})),
        atable.table_key(atable.table_parameters(PROBE, **{**SMALL, "n_lags": 5})),
        atable.table_key(atable.table_parameters(CWProbe(), **SMALL)),
        atable.table_key(atable.table_parameters(PROBE, model="von_karman", **SMALL)),
    }
    assert len(keys) == 6


def test_unwritable_cache_still_gives_a_table(tmp_path):
    blocker = tmp_path / "file-not-dir"
    blocker.write_text("x")
    params = {**SMALL, "height_range_m": (80.0, 110.0), "n_lags": 2}
    tab = get_a_table(PROBE, cache_dir=blocker / "sub", mu_max=0.5, **params)
    assert np.isfinite(tab.evaluate(2, 90.0, 0.3)[1])


def test_cw_table_uses_range_dependent_rayleigh_length(tmp_path):
    probe = CWProbe(0.0013)
    phi = 60.0
    tab = get_a_table(
        probe,
        phi_deg=phi,
        delta_theta_deg=7.2,
        n_lags=2,
        cache_dir=tmp_path,
        height_range_m=(40.0, 70.0),
        mu_max=0.5,
    )
    h = 55.0
    dy = _dy(h, phi, 7.2)
    rng = h / math.sin(math.radians(phi))
    # default cw probe: one spectrum per azimuth, no sweep averaging (H_perp = 1,
    # Banakh et al. (1999), eq. 15)
    direct = a_perp(2 * dy, probe=probe, dy=0.0, range_m=rng)
    assert float(tab.evaluate(2, h, 0.0)[0]) == pytest.approx(float(direct), rel=1e-4)
    swept = CWProbe(0.0013, transverse_averaging=True)
    tab_s = get_a_table(
        swept,
        phi_deg=phi,
        delta_theta_deg=7.2,
        n_lags=2,
        cache_dir=tmp_path,
        height_range_m=(40.0, 70.0),
        mu_max=0.5,
    )
    direct_s = a_perp(2 * dy, probe=swept, dy=dy, range_m=rng)
    assert float(tab_s.evaluate(2, h, 0.0)[0]) == pytest.approx(float(direct_s), rel=1e-4)
    assert float(direct_s) < float(direct)  # the sweep averages out small scales


def test_finite_outer_scale_table(tmp_path):
    params = {**SMALL, "height_range_m": (90.0, 120.0), "n_lags": 2}
    tab = get_a_table(
        PROBE,
        model="von_karman",
        cache_dir=tmp_path,
        mu_max=0.5,
        outer_scale_range_m=(60.0, 100.0),
        **params,
    )
    with pytest.raises(ValueError, match="outer_scale_m"):
        tab.evaluate(2, 100.0, 0.2)
    h, big_l, mu = 104.0, 77.0, 0.33
    dy = _dy(h)
    a1_t, a2_t = tab.evaluate(2, h, mu, big_l)
    d2 = a2(2, dy, mu, PHI, probe=PROBE, model="von_karman", outer_scale_m=big_l)
    d1 = a_perp(2 * dy, probe=PROBE, dy=dy, model="von_karman", outer_scale_m=big_l)
    assert float(a2_t) == pytest.approx(float(d2), rel=1e-4)
    assert float(a1_t) == pytest.approx(float(d1), rel=1e-4)
    assert np.isnan(tab.evaluate(2, h, mu, 500.0)[0])  # outer scale outside the table


def test_interpolation_is_exact_for_cubics():
    # 4-point Lagrange weights reproduce cubic polynomials in (log L, log h, mu) exactly
    heights = np.geomspace(10.0, 3000.0, 12)
    mu_nodes = atable.default_mu_grid(4.0)
    scales = np.geomspace(10.0, 3000.0, 9)
    lags = np.arange(1, 4)

    def poly(log_l, log_h, lag, mu):
        return 0.01 * log_l**3 - 0.02 * log_h**2 * log_l + 0.03 * mu**3 + log_h * mu + lag

    ll, lh = np.log(scales), np.log(heights)
    tab = ATable(
        heights,
        mu_nodes,
        scales,
        poly(ll[:, None, None], lh[None, :, None], lags[None, None, :], 0.0),
        poly(ll[:, None, None, None], lh[None, :, None, None], lags[None, None, :, None], mu_nodes),
        {"model": "von_karman", "phi_deg": PHI, "delta_theta_deg": DTHETA},
    )
    rng = np.random.default_rng(7)
    h = rng.uniform(10.0, 3000.0, 200)
    mu = rng.uniform(0.0, 4.0, 200)
    big_l = rng.uniform(10.0, 3000.0, 200)
    lag = rng.integers(1, 4, 200)
    a1_v, a2_v = tab.evaluate(lag, h, mu, big_l)
    np.testing.assert_allclose(a1_v, np.exp(poly(np.log(big_l), np.log(h), lag, 0.0)), rtol=1e-11)
    np.testing.assert_allclose(a2_v, np.exp(poly(np.log(big_l), np.log(h), lag, mu)), rtol=1e-11)


def test_cell_table_equals_evaluate():
    # ATable.at_cells: the height and mu weights applied once, L_V interpolated later;
    # the same Lagrange interpolation, so equal to evaluate up to rounding, NaN included
    heights = np.geomspace(10.0, 3000.0, 12)
    mu_nodes = atable.default_mu_grid(4.0)
    scales = np.geomspace(10.0, 3000.0, 9)
    rng = np.random.default_rng(3)
    log_a1 = rng.normal(size=(scales.size, heights.size, 3))
    log_a2 = rng.normal(size=(scales.size, heights.size, 3, mu_nodes.size))
    tab = ATable(heights, mu_nodes, scales, log_a1, log_a2, {"model": "von_karman"})
    n = 300
    h = rng.uniform(5.0, 3100.0, n)  # a few outside the heights: NaN
    mu = rng.uniform(0.0, 4.5, n)  # and outside mu: NaN in A_2 only
    big_l = rng.uniform(8.0, 3200.0, (n, 5))  # and outside L_V
    lags = np.arange(1, 4)
    cells = tab.at_cells(lags, h, mu)
    a1_c, a2_c = cells.evaluate(big_l)
    a1_e, a2_e = tab.evaluate(lags, h[:, None, None], mu[:, None, None], big_l[:, :, None])
    for got, want in ((a1_c, a1_e), (a2_c, a2_e)):
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
        np.testing.assert_allclose(got, want, rtol=1e-12)
    assert np.isnan(a2_e).any() and np.isfinite(a2_e).any()
    rows = np.array([7, 3, 250])
    none, a2_r = cells.evaluate(big_l[rows, :2], rows, a1=False)
    assert none is None
    np.testing.assert_allclose(a2_r, a2_e[rows, :2], rtol=1e-12)


@pytest.fixture(scope="module")
def stare_table(cache):
    # 24-ray step-stare VAD (15 deg steps): exact two-beam geometry, no sweep
    return get_a_table(
        PROBE,
        phi_deg=PHI,
        delta_theta_deg=15.0,
        n_lags=3,
        cache_dir=cache,
        height_range_m=(150.0, 600.0),
        mu_max=3.0,
        swept=False,
    )


def _direct_pairs(lag: int, mu: float, mids_deg: np.ndarray, wind_to_deg: float) -> float:
    """Mean exact two-beam A over pairs centred on ``mids_deg`` (clockwise scan, V_s = 1)."""
    from cwproc.physics import two_beam

    h = 300.0
    rng = h / math.sin(math.radians(PHI))
    radius = rng * math.cos(math.radians(PHI))
    t0 = math.radians(15.0) * radius  # ray period with V_s = 1 m/s
    a = math.radians(wind_to_deg)
    wind = mu * np.array([0.0, math.cos(a), math.sin(a)])
    d = two_beam.two_beam_structure_function(
        mids_deg - 7.5 * lag,
        mids_deg + 7.5 * lag,
        PHI,
        rng,
        probe=PROBE,
        time_separation_s=-lag * t0,
        mean_wind=wind,
    )
    return float(np.mean(d))


@pytest.mark.parametrize("mu", [0.0, 0.5, 1.5])
def test_two_beam_table_matches_exact_pairs(stare_table, mu):
    # full circle: the table (eq. 15 times the point-probe geometry ratio) against the
    # exact two-beam model of the probe, within 0.6 % (module doc of geometry_correction)
    mids = np.arange(0.0, 360.0, 10.0)
    for lag in (1, 2, 3):
        direct = _direct_pairs(lag, mu, mids, 70.0)
        assert float(stare_table.evaluate(lag, 300.0, mu)[1]) == pytest.approx(direct, rel=6e-3)


def test_sector_average_uses_the_azimuth_bins(stare_table):
    # a 90 deg sector: the average over the pairs present, not the full circle; per
    # azimuth the composite table (eq. 15 x point-probe geometry ratio) is within 5 % of
    # the exact pair where the transport shortens the separation to the probe length
    mids = np.arange(7.5, 90.0, 2.5)
    wind_to, mu = 70.0, 1.0
    weights = azimuth_bin_weights(np.radians(wind_to - mids))
    for lag in (1, 3):
        direct = _direct_pairs(lag, mu, mids, wind_to)
        full = float(stare_table.evaluate(lag, 300.0, mu)[1])
        sector = float(stare_table.evaluate(lag, 300.0, mu, weights=weights)[1])
        assert sector == pytest.approx(direct, rel=2.5e-2)
        assert abs(full / direct - 1) > 4 * abs(sector / direct - 1)


@pytest.mark.parametrize("mu", [0.0, 0.5, 1.5])
def test_swept_rays_seen_at_their_own_times(cache, mu):
    # a continuous 72-ray scan (5 deg swept per ray, 0.5 s per ray): the table against the
    # exact two-beam model whose rays average while the field moves (ray_duration_s);
    # 12 sub-beams per ray in the direct model, so 2.5 %
    from cwproc.physics import two_beam

    tab = get_a_table(
        PROBE,
        phi_deg=PHI,
        delta_theta_deg=5.0,
        n_lags=3,
        cache_dir=cache,
        height_range_m=(150.0, 600.0),
        mu_max=2.0,
        swept=True,
    )
    h = 300.0
    rng = h / math.sin(math.radians(PHI))
    radius = rng * math.cos(math.radians(PHI))
    t0 = 0.5
    speed = mu * math.radians(5.0) * radius / t0
    a = math.radians(70.0)
    wind = speed * np.array([0.0, math.cos(a), math.sin(a)])
    q = two_beam.beam_quadrature(PROBE, rng)
    mids = np.arange(0.0, 360.0, 10.0)
    for lag in (1, 3):
        direct = two_beam.two_beam_structure_function(
            mids - 2.5 * lag,
            mids + 2.5 * lag,
            PHI,
            rng,
            quadrature=q,
            time_separation_s=-lag * t0,
            mean_wind=wind,
            sweep_deg=5.0,
            n_sweep=12,
            ray_duration_s=t0,
        ).mean()
        assert float(tab.evaluate(lag, h, mu)[1]) == pytest.approx(float(direct), rel=2.5e-2)


class _Terminal:
    """A stand-in for stderr: records what is written, says whether it is a terminal."""

    def __init__(self, tty: bool) -> None:
        self.tty, self.text = tty, ""

    def isatty(self) -> bool:
        return self.tty

    def write(self, text: str) -> int:
        self.text += text
        return len(text)

    def flush(self) -> None:
        pass


@pytest.mark.parametrize("on", [True, False])
def test_a_table_build_shows_progress_only_when_turned_on(tmp_path, monkeypatch, on):
    """The first run was silent for 40 s while a table was built (issue 14, point 6): a
    bar over the table's heights (:mod:`cwproc.progress`) when the command line turned
    progress on; logs and pipes (batch, cron), notebooks and tests stay clean, and a
    cached table is loaded without a bar."""
    import sys

    from cwproc import progress

    err = _Terminal(True)
    monkeypatch.setattr(sys, "stderr", err)
    monkeypatch.setattr(progress, "DELAY_S", 0.0)
    params = {**SMALL, "height_range_m": (80.0, 110.0), "n_lags": 2}
    with progress.reporting(on):
        get_a_table(PROBE, cache_dir=tmp_path, mu_max=0.5, **params)
        if not on:
            assert err.text == ""
            return
        assert "A-table (inertial)" in err.text
        err.text = ""
        get_a_table(PROBE, cache_dir=tmp_path, mu_max=0.5, **params)
    assert err.text == "", "a cached table is loaded silently"
