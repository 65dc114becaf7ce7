"""The stare quicklook (``cwproc plot`` of a stare product): data in every panel of a
normal and a one-window product, a reason in the eps panel of a day without VADs, and
a refusal for a product with no finite value, in the style of tests/test_plots.py."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from cwproc import plots
from cwproc.cli import main
from cwproc.errors import ProductError
from cwproc.plots.stare import w_per_ray
from cwproc.products.writer import write_product

pytest.importorskip("matplotlib")

WINDOW_S = 300.0
RAY_S = 4.0


def stare_product(n_windows: int = 12, n_height: int = 8) -> xr.Dataset:
    """A stare product as ``stages.stare`` makes it: window statistics and w per ray."""
    rng = np.random.default_rng(3)
    t0 = np.datetime64("2024-01-01T00:00", "ns")
    centre = t0 + (np.arange(n_windows) * WINDOW_S + WINDOW_S / 2).astype("timedelta64[s]")
    rays = int(WINDOW_S / RAY_S)
    seconds = np.arange(n_windows * rays) * RAY_S
    seconds[seconds >= 4 * WINDOW_S] += 120.0  # a VAD between the stares: a gap
    ray_time = t0 + (seconds * 1e9).astype("timedelta64[ns]")
    h = 45.0 + 30.0 * np.arange(n_height)
    eps = 1e-3 * np.exp(-h / 400.0)[None, :] * rng.lognormal(0, 0.4, (n_windows, n_height))
    var = 0.6 * eps ** (2 / 3) / 1e-2
    dims = ("time", "height")
    ds = xr.Dataset(
        {
            "w_mean": (dims, rng.normal(0, 0.2, eps.shape)),
            "w_variance_corrected": (dims, var),
            "epsilon_stare": (dims, eps),
            "stare_flag": (dims, np.zeros(eps.shape, dtype=np.int8)),
            "w_ray": (("ray", "height"), rng.normal(0, 0.7, (ray_time.size, n_height))),
        },
        coords={
            "time": centre.astype("datetime64[ns]"),
            "height": h,
            "ray_time": ("ray", ray_time),
        },
        attrs={"window_s": WINDOW_S},
    )
    ds["epsilon_stare"][2:4, 5:] = np.nan  # a gap stays a gap
    return ds


def one_window(ds: xr.Dataset) -> xr.Dataset:
    first = ds["ray_time"].values < ds["time"].values[0] + np.timedelta64(150, "s")
    return ds.isel(time=[0], ray=np.flatnonzero(first))


def all_missing(ds: xr.Dataset) -> xr.Dataset:
    out = ds.copy()
    for name, da in ds.data_vars.items():
        if np.issubdtype(da.dtype, np.floating):
            out[name] = da.where(False)
    return out


@pytest.mark.parametrize("variant", ["normal", "one-window"])
def test_stare_quicklook_draws_data_in_every_panel(variant, data_pixels):
    import matplotlib.pyplot as plt

    ds = stare_product() if variant == "normal" else one_window(stare_product())
    plots.check_variables(ds, "stare")
    fig = plots.plot_stare(ds)
    try:
        counts = data_pixels(fig)
    finally:
        plt.close(fig)
    assert len(counts) == 3, counts
    assert min(counts) > 40, f"{variant}: data pixels per panel {counts}"


def test_stare_quicklook_refuses_a_product_without_a_value():
    with pytest.raises(ProductError, match="no finite value"):
        plots.plot_stare(all_missing(stare_product()))


def test_a_day_without_vads_says_why_eps_is_missing(data_pixels):
    import matplotlib.pyplot as plt

    ds = stare_product()
    ds["epsilon_stare"] = ds["epsilon_stare"].where(False)
    ds["stare_flag"] = ds["stare_flag"] | np.int8(1)
    fig = plots.plot_stare(ds)
    try:
        texts = [t.get_text() for ax in fig.axes for t in ax.texts]
        counts = data_pixels(fig)
    finally:
        plt.close(fig)
    assert "no value: no VAD wind this day (flag 1)" in texts
    assert counts[0] > 40 and counts[1] > 40 and counts[2] == 0, counts


def test_per_ray_panel_thins_the_rays_and_keeps_the_gaps():
    ds = stare_product()
    field, step = w_per_ray(ds)
    assert step == 1
    assert field.sizes["time"] == ds.sizes["ray"] + 1  # one NaN column in the VAD gap
    assert np.isnan(field.values).all(axis=1).sum() == 1
    many = stare_product(n_windows=120)  # 9000 rays of 4 s over 10 h: one in 5 kept
    field, step = w_per_ray(many)
    assert step == 5 and field.sizes["time"] == 9000 // 5 + 1


def test_cli_plots_a_stare_product_by_default_and_refuses_an_empty_one(tmp_path):
    path = write_product(
        stare_product(), tmp_path / "s_stare.nc", product="stare", title="t", summary="s"
    )
    res = CliRunner().invoke(main, ["plot", str(path), "-o", str(tmp_path / "s.png")])
    assert res.exit_code == 0, res.output
    import matplotlib.image as mpimg

    img = mpimg.imread(tmp_path / "s.png")
    assert img.shape[:2] == (plots.FIGSIZE[1] * plots.DPI, plots.FIGSIZE[0] * plots.DPI)
    empty = write_product(
        all_missing(stare_product()),
        tmp_path / "e_stare.nc",
        product="stare",
        title="t",
        summary="s",
    )
    res = CliRunner().invoke(main, ["plot", str(empty), "-o", str(tmp_path / "e.png")])
    assert res.exit_code == 1
    assert "cannot draw 'stare'" in res.output and "no finite value" in res.output
    assert not (tmp_path / "e.png").exists()
    res = CliRunner().invoke(
        main, ["plot", str(path), "-o", str(tmp_path / "x.png"), "--kind", "stare", "--scan", "1"]
    )
    assert res.exit_code == 2 and "--scan is used by --kind vad, not stare" in res.output


def test_a_stare_product_is_drawn_as_stare_by_default():
    assert plots.default_kind(stare_product()) == "stare"
