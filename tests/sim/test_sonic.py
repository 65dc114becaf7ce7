"""Virtual sonic: prescribed structure functions (Gladkikh et al. (2014), eq. 7)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cwproc.io.meteo2 import read_meteo2
from cwproc.physics.structure_functions import structure_function_fft
from cwproc.sim.sonic import (
    METEO2_RATE_HZ,
    SFModel,
    default_models,
    iter_sonic_chunks,
    simulate_sonic_dataset,
    sonic_truth,
    write_simulation,
)


def test_model_shapes_follow_eqs_4_to_6():
    x = np.linspace(-1, 1.5, 11)
    assert np.allclose(SFModel(1, slope=0.6).lg_dn(x), 0.6 * x)
    assert np.allclose(SFModel(2, a1=0.8, a2=-0.2).lg_dn(x), 0.8 * x - 0.2 * x**2)
    m3 = SFModel(3, a1=0.8, a2=-0.4, slope=0.7, r_s_m=3.0)
    xs = np.log10(3.0)
    # continuous at r_S, slope gamma beyond it
    assert m3.lg_dn(np.array([xs - 1e-9]))[0] == pytest.approx(m3.lg_dn(np.array([xs]))[0])
    assert m3.lg_dn(np.array([xs + 1]))[0] - m3.lg_dn(np.array([xs]))[0] == pytest.approx(0.7)
    # D(1 m) = C and constant beyond r_out
    m = SFModel(1, c_m2s2=0.07, r_out_m=20.0)
    assert m.structure_function(np.array([1.0]))[0] == pytest.approx(0.07)
    assert m.structure_function(np.array([30.0, 50.0])) == pytest.approx([0.07 * 20 ** (2 / 3)] * 2)


@pytest.mark.parametrize("sf_type", [1, 2, 3])
def test_circulant_embedding_is_nearly_exact(sf_type):
    assert sonic_truth(hours=1, sf_type=sf_type).negative_eigenvalue_share < 1e-3


def test_series_has_the_prescribed_structure_function():
    ds = simulate_sonic_dataset(hours=3, sf_type=2, seed=3, speed=5.0, direction_deg=0.0)
    model = default_models(2)[0]
    u = ds["u"].values.reshape(-1, 6420)  # direction 0: u is longitudinal
    d, _ = structure_function_fft(u, 200)
    d_mean = d.mean(axis=0)
    for j in (2, 10, 50, 150):
        r = j * 5.0 / METEO2_RATE_HZ
        # 18 windows: the mean empirical D within 10 % of the prescribed one
        assert d_mean[j - 1] == pytest.approx(model.structure_function(np.array([r]))[0], rel=0.1)


def test_sampling_clock_and_seeds():
    a = simulate_sonic_dataset(hours=0.2, sf_type=1, seed=1)
    b = simulate_sonic_dataset(hours=0.2, sf_type=1, seed=1)
    c = simulate_sonic_dataset(hours=0.2, sf_type=1, seed=2)
    assert a.sizes["time"] == 7704  # 720 s x 10.7 Hz
    dt = np.diff(a["time"].values).astype(np.int64)
    assert np.all(np.abs(dt - 1e9 / METEO2_RATE_HZ) <= 1)
    np.testing.assert_array_equal(a["u"].values, b["u"].values)
    assert not np.allclose(a["u"].values, c["u"].values)
    mean_speed = np.hypot(a["u"].mean(), a["v"].mean())
    assert float(mean_speed) == pytest.approx(6.0, abs=0.5)


def test_chunks_are_window_aligned_and_bounded():
    chunks = list(iter_sonic_chunks(hours=2.5, sf_type=1, seed=0))
    assert [c.sizes["time"] for c in chunks] == [38520, 38520, 19260]
    t1 = chunks[1]["time"].values[0]
    assert str(t1).startswith("2014-06-01T01:00:00")


def test_write_simulation_gives_meteo2_files_and_truth(tmp_path):
    files, truth = write_simulation(tmp_path, hours=0.25, sf_type=3, seed=4)
    assert len(files) == 1 and files[0].read_text().startswith("# cwproc meteo2")
    t = json.loads(truth.read_text())
    assert t["sf_type"] == 3 and len(t["models"]) == 3 and t["seed"] == 4
    ds = read_meteo2(files[0])
    ref = simulate_sonic_dataset(hours=0.25, sf_type=3, seed=4)
    assert ds.sizes["time"] == ref.sizes["time"]
    np.testing.assert_allclose(ds["u"].values, ref["u"].values, atol=5e-4)
    assert ds.attrs["sampling_rate_hz"] == pytest.approx(METEO2_RATE_HZ, rel=1e-4)
