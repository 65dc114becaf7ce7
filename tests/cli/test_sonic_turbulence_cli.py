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
