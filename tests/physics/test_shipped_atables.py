"""The A-tables shipped in the package (tools/build_atables.py): found by the README main
job with an empty user cache (no build), and equal to a rebuild."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.tables import atable

SAMPLE = Path(__file__).parents[2] / "sample_data"
SHIPPED = Path(atable.shipped_path("x")).parent


def _main_job(tmp_path: Path) -> None:
    res = CliRunner().invoke(
        main,
        ["retrieve", str(SAMPLE), "-c", str(SAMPLE / "site.toml"), "-o", str(tmp_path / "out")],
    )
    assert res.exit_code == 0, res.output


def test_every_shipped_table_is_listed_and_loads_under_its_key():
    tables = sorted(SHIPPED.glob("atable-*.npz"))
    assert tables, "no shipped A-table: run python tools/build_atables.py"
    listed = (SHIPPED / "MANIFEST.txt").read_text()
    for path in tables:
        assert path.name in listed
        key = path.stem.removeprefix("atable-")
        with np.load(path) as data:
            assert str(data["key"]) == key
            assert np.isfinite(data["log_a2"]).all()


def test_every_shipped_table_is_the_one_the_current_code_requests():
    """A shipped table's key holds the hash of the physics code (``params["code"]``): a
    change of that code without ``python tools/build_atables.py --rebuild`` leaves
    tables no request finds, and fails here (cheaply, without a retrieval)."""
    entries = [
        line.split()[0]
        for line in (SHIPPED / "MANIFEST.txt").read_text().splitlines()
        if line.strip() and not line.startswith("#")
    ]
    assert entries
    for name in entries:
        with np.load(SHIPPED / name) as data:
            params = json.loads(str(data["params"]))
        assert params["code"] == atable.code_version(), (
            f"{name} was built by other code: run python tools/build_atables.py --rebuild"
        )
        requested = atable.table_parameters(
            atable.probe_from_params(params["probe"]),
            **{k: params[k] for k in ("phi_deg", "delta_theta_deg", "n_lags", "model")},
            height_range_m=tuple(params["height_range_m"]),
            mu_max=params["mu_max"],
            swept=params["swept"],
            geometry=params["geometry"],
            **(
                {}
                if params["outer_scale_range_m"] is None
                else {"outer_scale_range_m": tuple(params["outer_scale_range_m"])}
            ),
        )
        assert name == f"atable-{atable.table_key(requested)}.npz"


def test_main_job_uses_the_shipped_tables(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    _main_job(tmp_path)
    assert not list((tmp_path / "cache").rglob("atable-*.npz")), "a table was built"


@pytest.mark.slow
def test_shipped_tables_equal_a_rebuild(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(atable, "shipped_path", lambda key: tmp_path / "none.npz")
    _main_job(tmp_path)
    built = sorted((tmp_path / "cache").rglob("atable-*.npz"))
    assert built
    for path in built:
        shipped = SHIPPED / path.name
        assert shipped.exists(), f"{path.name} is not shipped: run tools/build_atables.py"
        with np.load(path) as new, np.load(shipped) as old:
            # the shipped file also holds the table's parameters (tools/build_atables.py)
            assert sorted(new.files) == sorted(set(old.files) - {"params"})
            for name in new.files:
                # equal up to the host's arithmetic: another CPU, libm or BLAS thread count
                # moves A by ~2e-11 and the cw azimuth-bin ratios by ~2e-8 (seen between two
                # hosts of this kind); a physics change moves them by 1e-6 or more
                if np.issubdtype(new[name].dtype, np.floating):
                    np.testing.assert_allclose(
                        new[name], old[name], rtol=1e-7, atol=1e-12, err_msg=name
                    )
                else:
                    np.testing.assert_array_equal(new[name], old[name], err_msg=name)
