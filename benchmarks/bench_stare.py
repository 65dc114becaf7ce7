"""Stare eps (O'Connor et al. (2010)) against the truth, the conical eps and doppy (issue 13).

Prints four tables:

1. ``truth``: exact-statistics stares (:func:`cwproc.sim.stare.gaussian_stares`, a
   Kolmogorov field, the pulsed range weighting, 1.33 s rays, U = 5 m/s, SNR = 0.02 so
   sigma_e = 0.14 m/s) through :func:`cwproc.stages.stare.stare_product`: median and
   mean of eps_hat/eps, the spread of ln eps_hat, and the share of windows whose
   +-1 SE interval holds the truth, for eps = 1e-4 .. 1e-1.
2. ``same field``: ``cwproc simulate lidar --scan mixed`` (a VAD every 15 min, stares in
   between, one frozen von Karman field, L_V = 500 m) then ``cwproc retrieve``: per
   height, the day-mean stare eps and the conical eps (Smalikho (2020)) over the truth,
   and whether they agree within twice their combined standard errors.
3. ``doppy (simulated)``: doppy's ``Turbulence.from_winds`` (the code Cloudnet runs) on
   the same stare rays with the wind of cwproc's VAD product interpolated as Cloudnet
   does (linear, nearest beyond), over cwproc's stare eps, per height.
4. ``doppy (real)``: the real stare files (1-2 rays each, no VAD that day, so an assumed
   U = 5 m/s), per height: doppy's eps over cwproc's estimator on the same rays.

Run::

    python benchmarks/bench_stare.py            # about 1 min
    python benchmarks/bench_stare.py --quick    # 100 windows, a 2-hour cycle
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.physics import stare as ps
from cwproc.physics.dissipation import epsilon_from_band_variance
from cwproc.physics.noise import bandwidth_from_resolution, velocity_noise_std
from cwproc.sim.stare import gaussian_stares, stare_windows_dataset
from cwproc.stages.stare import StareOptions, noise_std_per_ray, stare_product

RAY_S = 20000 / 15000.0
WINDOW_S = 300.0
REAL = Path(__file__).resolve().parents[2] / "shared" / "real_data" / "hpl"


def stare_dataset(w: np.ndarray, snr: float) -> xr.Dataset:
    """Windows of stare rays (one gate at 300 m) as a canonical scan dataset."""
    return stare_windows_dataset(w, snr, window_s=WINDOW_S, ray_s=RAY_S)


def constant_wind(speed: float) -> xr.Dataset:
    return xr.Dataset(
        {
            "wind_speed": (("time", "height"), np.full((2, 2), speed)),
            "wind_speed_error": (("time", "height"), np.zeros((2, 2))),
        },
        coords={
            "time": np.array(["2000-01-01", "2100-01-01"], dtype="datetime64[ns]"),
            "height": [0.0, 5000.0],
        },
    )


def truth_table(n_windows: int) -> None:
    snr = 0.02
    noise = float(velocity_noise_std(snr, 10, 20000, bandwidth_from_resolution(0.0382)))
    n_ray = round(WINDOW_S / RAY_S)
    print(f"1. truth: {n_windows} windows of {WINDOW_S:g} s, sigma_e = {noise:.3f} m/s")
    print("   eps      median  mean   sd(ln)  in +-1SE")
    for eps in (1e-4, 1e-3, 1e-2, 1e-1):
        w = gaussian_stares(
            n_windows,
            n_ray,
            epsilon=eps,
            noise_std_m_s=noise,
            seed=11,
            ray_duration_s=RAY_S,
            wind_speed_m_s=5.0,
        )
        p = stare_product(stare_dataset(w, snr), constant_wind(5.0), StareOptions())
        e = p["epsilon_stare"].values[:, 0]
        se = p["epsilon_stare_standard_error"].values[:, 0]
        print(
            f"   {eps:7.0e}  {np.median(e) / eps:5.2f}  {np.mean(e) / eps:5.2f}  "
            f"{np.std(np.log(e)):5.2f}   {np.mean(np.abs(e - eps) <= se):4.2f}"
        )


def simulate_cycle(folder: Path, hours: float) -> None:
    simulate = ["simulate", "lidar", "-o", str(folder), "--scan", "mixed"]
    for args in (
        [*simulate, "--hours", str(hours), "--outer-scale", "500"],
        ["retrieve", str(folder / "data"), "-o", str(folder / "out"), "-q"],
    ):
        subprocess.run([sys.executable, "-m", "cwproc", *args], check=True, capture_output=True)


def same_field_table(folder: Path) -> None:
    out = folder / "out"
    s = xr.open_dataset(next(out.glob("*_stare.nc")))
    t = xr.open_dataset(next(out.glob("*_turbulence.nc")))
    eps_true = 0.01
    es, ses = s["epsilon_stare"].values, s["epsilon_stare_standard_error"].values
    n = np.sum(np.isfinite(es), axis=0)
    day = np.nanmean(es, axis=0)
    day_se = np.sqrt(np.nansum(ses**2, axis=0)) / n
    good = t["turbulence_flag"].values[0] & ~np.int8(32) == 0
    cone = np.interp(s["height"].values, t["height"].values[good], t["epsilon"].values[0, good])
    cone_se = np.interp(
        s["height"].values, t["height"].values[good], t["epsilon_standard_error"].values[0, good]
    )
    print("2. same field (stare day mean and conical block, over the truth 0.01)")
    print("   height  stare  +-SE   conical  +-SE   agree(2 SE)")
    agree = []
    for j, h in enumerate(s["height"].values):
        if h < 100 or h > t["height"].values[good].max():
            continue
        ok = abs(day[j] - cone[j]) <= 2 * np.hypot(day_se[j], cone_se[j])
        agree.append(ok)
        print(
            f"   {h:6.0f}  {day[j] / eps_true:5.2f}  {day_se[j] / eps_true:4.2f}   "
            f"{cone[j] / eps_true:5.2f}  {cone_se[j] / eps_true:4.2f}   {'yes' if ok else 'NO'}"
        )
    print(f"   agree at {sum(agree)} of {len(agree)} heights")


def doppy_eps(
    time: np.ndarray,
    height: np.ndarray,
    w: np.ndarray,
    speed: np.ndarray,
    t_ray: float,
    period: float,
) -> np.ndarray:
    from doppy.product.turbulence import HorizontalWind, Options, Turbulence, VerticalWind

    t = time.astype("datetime64[us]")
    vert = VerticalWind(time=t, height=height, w=np.nan_to_num(w), mask=~np.isfinite(w))
    hori = HorizontalWind(time=t, height=height, V=speed)
    turb = Turbulence.from_winds(vert, hori, Options(ray_accumulation_time=t_ray, period=period))
    e = turb.turbulent_kinetic_energy_dissipation_rate
    return np.where(turb.mask, np.nan, e)


def doppy_simulated_table(folder: Path) -> None:
    from cwproc.config import load_config
    from cwproc.io.halo_files import read_hpl_files
    from cwproc.pipeline import process_scan_day

    files = sorted((folder / "data").glob("*.hpl"))
    scans = read_hpl_files(files)
    cfg = load_config("streamline")
    products = process_scan_day(scans, cfg, [])
    st = products["stare"]
    vertical = scans.isel(ray=np.flatnonzero(scans["elevation"].values > 85))
    w = st["w_ray"].values
    speed = np.column_stack(
        [
            np.interp(
                vertical["time"].values.astype(np.int64),
                st["time"].values.astype(np.int64),
                st["stare_wind_speed"].values[:, j],
            )
            for j in range(st.sizes["height"])
        ]
    )
    e_d = doppy_eps(vertical["time"].values, st["height"].values, w, speed, RAY_S, 180.0)
    ours = np.nanmedian(st["epsilon_stare"].values, axis=0)
    theirs = np.nanmedian(e_d, axis=0)
    print("3. doppy on the simulated stares (Cloudnet's 180 s window, the cwproc VAD wind)")
    print("   height  cwproc/truth  doppy/truth  doppy/cwproc")
    for j in range(0, st.sizes["height"], 3):
        h = st["height"].values[j]
        print(
            f"   {h:6.0f}  {ours[j] / 0.01:8.2f}  {theirs[j] / 0.01:10.2f}  "
            f"{theirs[j] / ours[j]:9.2f}"
        )
    l1, ln = 6.0 * 180.0, 6.0 * RAY_S
    model = (
        ps.band_variance_factor(l1, ln, 15.3, 18.0)[()]
        / (1.5 * ps.A_OCONNOR * (2 * np.pi) ** (-2 / 3) * (l1 ** (2 / 3) - ln ** (2 / 3)))
    ) ** 1.5
    print(
        f"   expected doppy/cwproc from the band factors alone (U = 6 m/s, T = 180 s): "
        f"{model:.2f}; doppy removes no noise"
    )


def doppy_real_table() -> None:
    from cwproc.io.halo import read_hpl
    from cwproc.stages.stare import split_stares

    print("4. real stares (1-2 rays; no VAD that day, U = 5 m/s assumed)")
    for path in sorted(REAL.glob("[a-z]*Stare*.hpl")):
        ds, _ = split_stares(read_hpl(path))
        p = stare_product(ds, constant_wind(5.0), StareOptions())
        w = p["w_ray"].values
        n = ds.sizes["ray"]
        t_ray = float(ds.attrs["pulses_per_ray"]) / 15000.0
        speed = np.full(w.shape, 5.0)
        if n < 2:
            print(f"   {path.name}: {n} ray: no variance, neither tool gives eps")
            continue
        e_d = doppy_eps(ds["time"].values, p["height"].values, w, speed, t_ray, 180.0)[0]
        # cwproc's estimator on the same two rays (the product needs 3 per window)
        span = float((ds["time"].values[-1] - ds["time"].values[0]) / np.timedelta64(1, "s"))
        both = np.isfinite(w).all(axis=0)  # heights where both rays pass the SNR screen
        var = np.full(w.shape[1], np.nan)
        share = (n - 1) / n  # white noise about the rays' own mean
        noise_var = np.mean(noise_std_per_ray(ds)[:, both] ** 2, 0)
        var[both] = np.var(w[:, both], axis=0) - share * noise_var
        g = ps.band_variance_factor(5.0 * (span + t_ray), 5.0 * t_ray, 15.3, 18.0)
        ours = epsilon_from_band_variance(var, g)
        ratio = e_d / ours
        ok = np.isfinite(ratio)
        print(
            f"   {path.name}: {n} rays, {ok.sum()} heights with both; doppy/cwproc median "
            f"{np.median(ratio[ok]):.2f} (quartiles {np.percentile(ratio[ok], 25):.2f}-"
            f"{np.percentile(ratio[ok], 75):.2f}); cwproc product: eps NaN, flag "
            f"{int(np.max(p['stare_flag'].values))} (fewer than 3 rays per variance window)"
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    truth_table(100 if args.quick else 300)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        simulate_cycle(folder, 2.0 if args.quick else 3.0)
        same_field_table(folder)
        try:
            import doppy  # noqa: F401
        except ImportError:
            print("3./4. doppy is not installed (pip install doppy): comparison skipped")
            return 0
        doppy_simulated_table(folder)
    if REAL.is_dir():
        doppy_real_table()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
