"""Quicklooks: every kind renders a non-blank PNG of the expected size; missing variables
give a clear error."""

from __future__ import annotations

import ast
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from click.testing import CliRunner

from cwproc import plots
from cwproc.cli import main
from cwproc.errors import ProductError
from cwproc.plots.axes import log_tick_values, sci_label
from cwproc.plots.turbulence import ratio_shown
from cwproc.products.writer import write_product

pytest.importorskip("matplotlib")


def _th(n_time=12, n_height=8):
    t = pd.date_range("2024-06-01", periods=n_time, freq="10min").values
    h = 50.0 + 30.0 * np.arange(n_height)
    return t, h


def wind_product() -> xr.Dataset:
    t, h = _th()
    rng = np.random.default_rng(0)
    speed = 5 + 0.02 * h[None, :] + rng.normal(0, 0.3, (t.size, h.size))
    dirn = np.full_like(speed, 240.0)
    u = -speed * np.sin(np.radians(dirn))
    v = -speed * np.cos(np.radians(dirn))
    ds = xr.Dataset(
        {
            "u": (("time", "height"), u),
            "v": (("time", "height"), v),
            "w": (("time", "height"), rng.normal(0, 0.2, speed.shape)),
            "wind_speed": (("time", "height"), speed),
            "wind_direction": (("time", "height"), dirn),
        },
        coords={"time": t, "height": h},
    )
    ds["wind_speed"][3:5, 4:] = np.nan  # a gap must stay a gap
    return ds


def turbulence_product() -> xr.Dataset:
    t, h = _th()
    lag = np.arange(1, 6)
    eps = 1e-3 * np.exp(-h / 300)[None, :] * np.ones((t.size, 1))
    a = 2.0 * (lag * 3.0) ** (2 / 3)
    sf = eps[..., None] ** (2 / 3) * a + 2 * 0.1**2
    return xr.Dataset(
        {
            "epsilon": (("time", "height"), eps),
            "epsilon_ratio": (
                ("time", "height"),
                1 + 0.5 * np.random.default_rng(1).random(eps.shape),
            ),
            "structure_function": (("time", "height", "lag"), sf),
            "structure_function_model": (("time", "height", "lag"), sf * 1.01),
            "noise_std": (("time", "height"), np.full(eps.shape, 0.1)),
            "transverse_resolution": (("time", "height"), np.full(eps.shape, 3.0)),
        },
        coords={"time": t, "height": h, "lag": lag},
    )


def sf_product() -> xr.Dataset:
    rng = np.random.default_rng(2)
    n_w, comps = 6, ["longitudinal", "transverse", "vertical"]
    r = np.geomspace(0.2, 30, 50)
    d = np.broadcast_to((r / 1.0) ** (2 / 3), (n_w, 3, r.size))
    return xr.Dataset(
        {
            "sf_type": (("window", "component"), rng.integers(0, 4, (n_w, 3))),
            "r_max": (("window", "component"), np.full((n_w, 3), 20.0)),
            "normalised_sf": (("window", "component", "lag"), d),
            "normalised_sf_fit": (("window", "component", "lag"), d),
            "lag_distance": (("window", "component", "lag"), np.broadcast_to(r, d.shape)),
        },
        coords={"component": comps, "window": np.arange(n_w)},
    )


def montecarlo_product() -> xr.Dataset:
    n = np.arange(1, 11)
    h = np.array([50.0, 100, 200, 300, 400, 500])
    base = 0.35 / np.sqrt(n)[:, None] * np.ones((1, h.size))
    return xr.Dataset(
        {
            k: (("n_scans", "height"), base * f)
            for k, f in [
                ("epsilon_rel_error", 1.0),
                ("variance_rel_error", 0.6),
                ("integral_scale_rel_error", 1.2),
            ]
        },
        coords={"n_scans": n, "height": h},
    )


def _assert_png(path, size=(plots.FIGSIZE[0] * plots.DPI, plots.FIGSIZE[1] * plots.DPI)):
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    assert img.shape[1] == int(size[0]) and img.shape[0] == int(size[1])
    assert img[..., :3].std() > 0.02  # not blank


@pytest.mark.parametrize(
    ("kind", "factory"),
    [
        ("wind", wind_product),
        ("epsilon", turbulence_product),
        ("structure", turbulence_product),
        ("sf-types", sf_product),
        ("sf-window", sf_product),
    ],
)
def test_every_kind_renders(tmp_path, kind, factory):
    out = plots.render(factory(), kind, tmp_path / f"{kind}.png")
    _assert_png(out)


def test_montecarlo_renders(tmp_path):
    out = plots.render(montecarlo_product(), "montecarlo", tmp_path / "mc.png")
    _assert_png(out, size=(1200, 450))


def test_missing_variables_named(tmp_path):
    with pytest.raises(ProductError, match="missing variable\\(s\\) epsilon_ratio"):
        plots.render(
            turbulence_product().drop_vars("epsilon_ratio"),
            "epsilon",
            tmp_path / "x.png",
            source="p.nc",
        )
    assert not (tmp_path / "x.png").exists()


def test_default_kind():
    assert plots.default_kind(wind_product()) == "wind"
    assert plots.default_kind(turbulence_product()) == "epsilon"
    assert plots.default_kind(montecarlo_product()) == "montecarlo"
    with pytest.raises(ProductError):
        plots.default_kind(xr.Dataset({"x": ("a", [1.0])}))


def test_cli_plot_product_and_missing_variables(tmp_path):
    wind = write_product(wind_product(), tmp_path / "w.nc", product="wind", title="t", summary="s")
    res = CliRunner().invoke(main, ["plot", str(wind), "-o", str(tmp_path / "w.png")])
    assert res.exit_code == 0, res.output
    _assert_png(tmp_path / "w.png")
    res = CliRunner().invoke(
        main, ["plot", str(wind), "-o", str(tmp_path / "e.png"), "--kind", "epsilon"]
    )
    assert res.exit_code == 1
    assert "missing variable(s) epsilon, epsilon_ratio" in res.output
    assert not (tmp_path / "e.png").exists()


def test_cli_plot_not_a_product(tmp_path):
    junk = tmp_path / "junk.nc"
    junk.write_text("not netcdf")
    res = CliRunner().invoke(main, ["plot", str(junk), "-o", str(tmp_path / "j.png")])
    assert res.exit_code == 1
    assert "junk.nc" in res.output and "not a readable NetCDF product" in res.output


# --- every kind on a one-time-step, a normal and an all-missing product ---------------


def _one_step(ds: xr.Dataset) -> xr.Dataset:
    for dim in ("time", "window", "n_scans"):
        if dim in ds.dims:
            return ds.isel({dim: [0]})
    raise AssertionError("no step dimension")


def _all_missing(ds: xr.Dataset) -> xr.Dataset:
    out = ds.copy()
    for name, da in ds.data_vars.items():
        if np.issubdtype(da.dtype, np.floating):
            out[name] = da.where(False)
    return out


KIND_FACTORIES = [
    ("wind", wind_product),
    ("epsilon", turbulence_product),
    ("structure", turbulence_product),
    ("sf-types", sf_product),
    ("sf-window", sf_product),
    ("montecarlo", montecarlo_product),
]


@pytest.mark.parametrize(("kind", "factory"), KIND_FACTORIES)
@pytest.mark.parametrize("variant", ["normal", "one-step", "all-missing"])
def test_every_kind_draws_data_or_refuses(kind, factory, variant, data_pixels):
    """A picture is either drawn with data in every panel or refused with a reason."""
    import matplotlib.pyplot as plt

    ds = {"normal": factory, "one-step": lambda: _one_step(factory()), "all-missing": None}[variant]
    ds = _all_missing(factory()) if ds is None else ds()
    plots.check_variables(ds, kind)
    try:
        fig = plots.KINDS[kind][0](ds)
    except ProductError as exc:
        assert variant == "all-missing", f"{kind} refused a {variant} product: {exc}"
        assert "no finite value" in str(exc) or "no structure function" in str(exc)
        return
    try:
        counts = data_pixels(fig)
    finally:
        plt.close(fig)
    if kind != "sf-types":  # sf_type is an integer: 'none' for every window is data
        assert variant != "all-missing", f"{kind} drew an all-missing product"
    assert counts and min(counts) > 40, f"{kind}/{variant}: data pixels per panel {counts}"


def test_epsilon_ratio_hidden_where_method1_is_empty():
    ds = turbulence_product()
    ds["epsilon_method1"] = ds["epsilon"] * ds["epsilon_ratio"]
    ds["epsilon_method1"][:, :3] = np.nan  # flag 4: mu beyond method 1
    shown = ratio_shown(ds)
    assert np.isnan(shown.values[:, :3]).all()
    assert np.isfinite(shown.values[:, 3:]).all()


def test_log_colour_bar_has_enough_ticks():
    assert log_tick_values(4.1e-3, 1.13e-2).size >= 4
    assert list(log_tick_values(1e-4, 1e-2)) == pytest.approx(
        [1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2]
    )
    assert sci_label(6e-3) == "$6\\times10^{-3}$"
    assert sci_label(1e-2) == "$10^{-2}$"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--kind", "structure", "--time-index", "99"], "time indices of"),
        (["--time-index", "1"], "--time-index is used by --kind structure"),
        (["--kind", "structure", "--height", "5000"], "--height 5000 is out of range"),
    ],
)
def test_cli_plot_arguments_checked(tmp_path, args, message):
    turb = write_product(
        turbulence_product(), tmp_path / "t.nc", product="turbulence", title="t", summary="s"
    )
    res = CliRunner().invoke(main, ["plot", str(turb), "-o", str(tmp_path / "t.png"), *args])
    assert res.exit_code == 2, res.output
    assert message in res.output and len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "t.png").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--kind", "sf-window", "--window", "99"], "--window 99 is out of range"),
        (["--kind", "sf-window", "--component", "lateral"], "longitudinal, transverse"),
    ],
)
def test_cli_plot_sonic_arguments_checked(tmp_path, args, message):
    sf = write_product(sf_product(), tmp_path / "s.nc", product="sf", title="t", summary="s")
    res = CliRunner().invoke(main, ["plot", str(sf), "-o", str(tmp_path / "s.png"), *args])
    assert res.exit_code == 2, res.output
    assert message in res.output and len(res.output.strip().splitlines()) == 1


def test_cli_plot_vad_scan_out_of_range(tmp_path):

    hpl = Path(__file__).parents[1] / "sample_data/streamline/VAD_999_20240601_120000.hpl"
    res = CliRunner().invoke(
        main, ["plot", str(hpl), "--kind", "vad", "--scan", "99", "-o", str(tmp_path / "v.png")]
    )
    assert res.exit_code == 2, res.output
    assert "--scan 99 is out of range" in res.output and "0 .. 5" in res.output


def test_png_gets_the_umask_mode(tmp_path):
    import os

    old = os.umask(0o022)
    try:
        out = plots.render(wind_product(), "wind", tmp_path / "w.png")
    finally:
        os.umask(old)
    assert out.stat().st_mode & 0o777 == 0o644
    assert not list(tmp_path.glob(".*tmp*"))


def test_png_temporary_is_unpredictable_and_follows_no_symlink(tmp_path):
    """plot wrote .<name>.tmp.png and followed a planted symlink (issue 17.6)."""
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    from cwproc.plots import save_png

    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    (tmp_path / ".out.png.tmp.png").symlink_to(victim)
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    old = os.umask(0o022)
    try:
        out = save_png(fig, tmp_path / "out.png")
    finally:
        os.umask(old)
    assert victim.read_text() == "keep me"
    assert out.read_bytes().startswith(b"\x89PNG")
    assert (out.stat().st_mode & 0o777) == 0o644


# --- the VAD picture of a scan file: normal, one scan, every velocity missing ----------

SAMPLE_HPL = (
    __import__("pathlib").Path(__file__).parents[1]
    / "sample_data/streamline/VAD_999_20240601_120000.hpl"
)


def _vad_variant(variant: str):
    """The sample scans (six), their first scan only, or every radial velocity missing;
    screened and fitted as ``cwproc plot --kind vad`` does."""
    from cwproc.config import Config
    from cwproc.pipeline import read_input
    from cwproc.stages import qc, vad

    cfg = Config()
    scans = read_input(str(SAMPLE_HPL), cfg).dataset
    if variant == "one-step":
        scans = scans.isel(ray=np.flatnonzero(scans["scan"].values == 0))
    elif variant == "all-missing":
        scans = scans.assign(radial_velocity=scans["radial_velocity"].where(False))
    screened = qc.screen_radial_velocity(
        scans, snr_min=cfg.qc.snr_min, outlier_threshold=cfg.qc.outlier_threshold
    )
    wind = vad.fit_vad(
        screened,
        min_rays=cfg.vad.min_rays,
        max_gap_deg=cfg.vad.max_gap_deg,
        reference_direction_deg=cfg.vad.reference_direction_deg,
        max_residual_std=cfg.vad.max_residual_std,
    )
    return screened, wind


@pytest.mark.parametrize("variant", ["normal", "one-step", "all-missing"])
def test_vad_draws_data_or_refuses(variant, data_pixels):
    """The seventh kind, on a scan file: data in both panels, or refused with a reason."""
    import matplotlib.pyplot as plt

    screened, wind = _vad_variant(variant)
    scan = 0 if variant == "one-step" else None
    try:
        fig = plots.plot_vad_fit(screened, wind, scan=scan)
    except ProductError as exc:
        assert variant == "all-missing", f"vad refused a {variant} scan file: {exc}"
        assert "has no VAD fit" in str(exc)
        return
    try:
        counts = data_pixels(fig)
    finally:
        plt.close(fig)
    assert variant != "all-missing", "vad drew a scan without one finite velocity"
    assert min(counts) > 40, f"vad/{variant}: data pixels per panel {counts}"


def _overlapping_labels(fig, axis) -> list[tuple[str, str]]:
    """Pairs of neighbouring tick labels of a horizontal axis whose boxes overlap."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    labels = sorted(
        (t for t in axis.get_ticklabels() if t.get_visible() and t.get_text()),
        key=lambda t: t.get_window_extent(renderer).x0,
    )
    boxes = [t.get_window_extent(renderer) for t in labels]
    return [
        (a.get_text(), b.get_text())
        for a, b, ba, bb in zip(labels, labels[1:], boxes, boxes[1:], strict=False)
        if ba.x1 > bb.x0
    ]


@pytest.mark.parametrize(("lo", "hi"), [(4.1e-3, 1.13e-2), (4e-3, 1.9e-2), (1e-5, 1e-1)])
def test_epsilon_profile_axis_labels_do_not_touch(lo, hi):
    """A one-block epsilon profile over part of a decade (labels 4x10^-3 .. 10^-2 were
    drawn over each other), with method 1 reaching beyond method 2: readable labels,
    at least two of them, and the axis covers every point drawn."""
    import matplotlib.pyplot as plt

    ds = _one_step(turbulence_product())
    h = ds["height"].values
    ds["epsilon"][:] = np.geomspace(lo, hi / 2, h.size)[None, :]
    ds["epsilon_method1"] = ds["epsilon"] * np.linspace(2, 1, h.size)[None, :]
    ds["epsilon_ratio"] = ds["epsilon_method1"] / ds["epsilon"]
    fig = plots.KINDS["epsilon"][0](ds)
    try:
        ax = fig.axes[0]
        assert _overlapping_labels(fig, ax.xaxis) == []
        labelled = [t for t in ax.get_xticks() if ax.get_xlim()[0] <= t <= ax.get_xlim()[1]]
        assert len(labelled) >= 2
        assert ax.get_xlim()[1] >= float(ds["epsilon_method1"].max())
    finally:
        plt.close(fig)


def test_refused_picture_names_the_file(tmp_path):
    empty = write_product(
        _all_missing(wind_product()), tmp_path / "empty.nc", product="wind", title="t", summary="s"
    )
    res = CliRunner().invoke(main, ["plot", str(empty), "-o", str(tmp_path / "e.png")])
    assert res.exit_code == 1
    assert "empty.nc: cannot draw 'wind'" in res.output and "no finite value" in res.output
    assert not (tmp_path / "e.png").exists()


PLOTS = Path(__file__).resolve().parents[1] / "cwproc" / "plots"


def private_imports(source: str) -> list[str]:
    """``line: module.name`` of every private name ``source`` takes from a cwproc module."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("cwproc"):
            for alias in node.names:
                if alias.name.startswith("_"):
                    found.append(f"{node.lineno}: {node.module}.{alias.name}")
    return found


def test_no_plot_module_takes_a_private_name_of_another():
    """Each module of the package says what it offers: no ``_pyplot`` across modules."""
    bad = [
        f"{path.name}:{hit}"
        for path in sorted(PLOTS.glob("*.py"))
        for hit in private_imports(path.read_text(encoding="utf-8"))
    ]
    assert not bad, "private names imported across plot modules:\n" + "\n".join(bad)
    assert private_imports("from cwproc.plots.figure import _units\n") == [
        "1: cwproc.plots.figure._units"
    ]
