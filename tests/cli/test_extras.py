"""matplotlib is checked before any work: an install without it (broken, or a package
removed since) gets one line saying to install cwproc again from its clone, exit status 2,
and nothing is computed or written."""

from __future__ import annotations

import importlib.util

import pytest
from click.testing import CliRunner

from cwproc.cli import main


@pytest.fixture
def no_matplotlib(monkeypatch):
    real = importlib.util.find_spec

    def find_spec(name, *args, **kwargs):
        if name == "matplotlib" or name.startswith("matplotlib."):
            return None
        return real(name, *args, **kwargs)

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)


def _one_line_exit_2(res, *needles):
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1, res.output
    for needle in needles:
        assert needle in lines[0]


def test_theory_eps_ratio_png_needs_plot_extra(tmp_path, no_matplotlib):
    res = CliRunner().invoke(
        main, ["theory", "eps-ratio", "--phi", "35.3", "--png", str(tmp_path / "r.png")]
    )
    _one_line_exit_2(res, "from the top of its clone: pip install .", "--png")
    assert "cwproc[plot]" not in res.output  # not the package index
    assert "eps1/eps2" not in res.output  # nothing computed


def test_simulate_montecarlo_needs_plot_extra_before_the_study(tmp_path, no_matplotlib):
    res = CliRunner().invoke(main, ["simulate", "montecarlo", "-o", str(tmp_path / "mc")])
    _one_line_exit_2(res, "pip install .", "--no-png")
    assert not (tmp_path / "mc").exists()


def test_plot_needs_plot_extra(tmp_path, no_matplotlib):
    src = tmp_path / "x.nc"
    src.write_bytes(b"")
    res = CliRunner().invoke(main, ["plot", str(src), "-o", str(tmp_path / "x.png")])
    _one_line_exit_2(res, "cwproc plot needs matplotlib")
