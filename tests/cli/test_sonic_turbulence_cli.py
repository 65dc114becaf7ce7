"""``cwproc sonic-turbulence`` end to end: virtual Meteo-2 files -> CF product."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io.netcdf import read_product


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    res = CliRunner().invoke(
        main, ["simulate", "sonic", "-o", str(out), "--type", "1", "--hours", "1", "--seed", "9"]
    )
    assert res.exit_code == 0, res.output
    return out


def test_product_recovers_the_truth_and_is_cf_compliant(simulated, tmp_path, compliance):
    config = tmp_path / "site.toml"
    config.write_text(
        '[output]\ninstitution = "IAO SB RAS"\ncreator_name = "A. Sonic"\n'
        'project = "test"\nlatitude = 56.48\nlongitude = 85.05\naltitude_m = 160.0\n'
    )
    res = CliRunner().invoke(
        main,
        [
            "sonic-turbulence",
            str(simulated),
            "-o",
            str(tmp_path),
            "-c",
            str(config),
            "--height",
            "10",
        ],
    )
    assert res.exit_code == 0, res.output
    (product,) = tmp_path.glob("meteo2_20140601_sonic-turbulence.nc")
    ds = read_product(product)
    truth = json.loads((simulated / "meteo2_sim_type1_truth.json").read_text())
    c = truth["models"][0]["c_m2s2"]
    eps_true = (c / 2.0) ** 1.5  # longitudinal, D = C r^(2/3) = 2.0 eps^(2/3) r^(2/3)
    eps = ds["epsilon_component"].values[:, 0]
    err = ds["epsilon_component_error"].values[:, 0]
    # Meteo-2 files keep 0.01 m/s: the quantisation adds white noise far below D(0.56 m)
    assert np.all(np.abs(eps - eps_true) < 4 * err + 0.03 * eps_true)
    assert ds["epsilon"].attrs["units"] == "m2 s-3"
    np.testing.assert_array_equal(ds["foken_flag"].attrs["flag_values"], [0, 1, 2])
    high, acdd = compliance(product)
    assert high == []
    assert acdd >= 0.7


def test_a_damaged_input_fails_alone_with_its_name(simulated, tmp_path):
    bad = tmp_path / "in" / "broken_meteo2.txt"
    bad.parent.mkdir()
    good = sorted(simulated.glob("*.txt"))[0]
    bad.write_text(good.read_text()[:300] + "\nthis is not a sonic line\n")
    res = CliRunner().invoke(
        main, ["sonic-turbulence", str(good), str(bad), "-o", str(tmp_path / "o"), "-q"]
    )
    assert res.exit_code == 1
    assert "broken_meteo2.txt" in res.output
    assert "Traceback" not in res.output
    assert len(list((tmp_path / "o").glob("*_sonic-turbulence.nc"))) == 1


@pytest.mark.parametrize("window", ["600", "1800"])
def test_window_option_sets_the_number_of_windows(simulated, tmp_path, window):
    res = CliRunner().invoke(
        main, ["sonic-turbulence", str(simulated), "-o", str(tmp_path), "-q", "--window", window]
    )
    assert res.exit_code == 0, res.output
    (product,) = tmp_path.glob("*_sonic-turbulence.nc")
    assert read_product(product).sizes["window"] == 3600 // int(window)


def test_real_csat3_window_against_an_independent_computation(real_data, tmp_path):
    """The 15-min CSAT3 file (20 Hz, fluxpart test data): variances, u_* and TKE of the
    product (without despiking) equal those computed here from the file with plain
    pandas/numpy (double rotation, linear detrending) to 1e-9 relative; despiking it
    (Vickers & Mahrt) replaces under 0.1 % of the samples."""
    import pandas as pd

    path = real_data / "sonic" / "TOA5_6843.ts_Above_2012_06_07_1245.dat"
    res = CliRunner().invoke(
        main, ["sonic-turbulence", str(path), "-o", str(tmp_path / "a"), "-q", "--window", "900"]
    )
    assert res.exit_code == 0, res.output
    despiked = read_product(next((tmp_path / "a").glob("toa5_*_sonic-turbulence.nc")))
    assert np.all(despiked["spike_fraction"].values[0] < 1e-3)
    args = ["sonic-turbulence", str(path), "-o", str(tmp_path / "b"), "-q", "--window", "900"]
    res = CliRunner().invoke(main, [*args, "--despike", "none"])
    assert res.exit_code == 0, res.output
    ds = read_product(next((tmp_path / "b").glob("toa5_*_sonic-turbulence.nc")))
    frame = pd.read_csv(path, skiprows=[0, 2, 3])
    stamp = pd.to_datetime(frame["TIMESTAMP"], format="mixed")
    frame = frame[stamp < pd.Timestamp("2012-06-07 13:00:00")]
    u, v, w = (frame[c].to_numpy(float) for c in ("Ux", "Uy", "Uz"))
    yaw = np.arctan2(v.mean(), u.mean())
    u1, v1 = u * np.cos(yaw) + v * np.sin(yaw), -u * np.sin(yaw) + v * np.cos(yaw)
    pitch = np.arctan2(w.mean(), u1.mean())
    u2, w2 = u1 * np.cos(pitch) + w * np.sin(pitch), -u1 * np.sin(pitch) + w * np.cos(pitch)
    t = np.arange(u.size)

    def fluct(x):
        return x - np.polyval(np.polyfit(t, x, 1), t)

    fu, fv, fw = fluct(u2), fluct(v1), fluct(w2)
    var = [np.mean(fu**2), np.mean(fv**2), np.mean(fw**2)]
    np.testing.assert_allclose(ds["velocity_variance"].values[0], var, rtol=1e-9)
    ustar = (np.mean(fu * fw) ** 2 + np.mean(fv * fw) ** 2) ** 0.25
    assert float(ds["friction_velocity"][0]) == pytest.approx(ustar, rel=1e-9)
    assert float(ds["tke"][0]) == pytest.approx(0.5 * sum(var), rel=1e-9)


def test_data_shorter_than_a_window_give_a_note_not_an_empty_product(tmp_path):
    """The shipped 10-min sonic samples under the default 30-min window: every window
    lacks valid samples, so no all-missing product is written and a note says why."""
    from pathlib import Path

    samples = Path(__file__).resolve().parents[2] / "sample_data" / "sonic"
    files = sorted(samples.glob("TOA5_*")) + sorted(samples.glob("meteo2_*"))
    assert files
    res = CliRunner().invoke(main, ["sonic-turbulence", *map(str, files), "-o", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert not list(tmp_path.glob("*.nc"))
    notes = [line for line in res.output.splitlines() if line.startswith("note:")]
    assert len(notes) == 2 and all("no window of 1800 s" in line for line in notes)
    assert all("--window" in line for line in notes)
    res = CliRunner().invoke(
        main, ["sonic-turbulence", *map(str, files), "-o", str(tmp_path), "--window", "300"]
    )
    assert res.exit_code == 0, res.output
    assert len(list(tmp_path.glob("*_sonic-turbulence.nc"))) == 2
