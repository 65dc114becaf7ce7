"""Speed and memory of qc + vad on a synthetic Stream Line day.

720 conical scans x 24 rays x 200 gates (one scan every 2 min), uniform wind with a
height profile, Gaussian noise of 0.3 m s-1, 2 % noise-gate outliers and 5 % low-SNR
gates. Prints the wall time of ``screen_radial_velocity`` and ``fit_vad``, the peak
traced Python memory, and the accuracy of the recovered wind against the truth.

Run: ``python benchmarks/bench_vad.py [--scans 720 --rays 24 --gates 200 --repeat 3]``;
ZephIR-like hour: ``python benchmarks/bench_vad.py --homodyne --scans 3600 --rays 50
--gates 10``.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np
import xarray as xr

from cwproc.physics.geometry import radial_velocity
from cwproc.physics.vad_errors import rms_error_full_circle
from cwproc.stages.qc import screen_radial_velocity
from cwproc.stages.vad import fit_vad


def synthetic_day(
    n_scans: int, n_rays: int, n_gates: int, seed: int = 0, homodyne: bool = False
) -> tuple[xr.Dataset, tuple[np.ndarray, np.ndarray]]:
    """A day of VAD scans at 60 deg elevation with known wind profile (homodyne: |V_r|)."""
    rng = np.random.default_rng(seed)
    n = n_scans * n_rays
    az = np.tile(np.arange(n_rays) * 360.0 / n_rays, n_scans)
    el = np.full(n, 60.0)
    ranges = 45.0 + 30.0 * np.arange(n_gates)
    u = 5.0 + 0.002 * ranges
    v = -3.0 + 0.001 * ranges
    vr = radial_velocity(u, v, 0.1, az[:, None], el[:, None])
    vr = vr + 0.3 * rng.standard_normal(vr.shape)
    bad = rng.random(vr.shape) < 0.02
    vr[bad] = rng.uniform(-20.0, 20.0, bad.sum())
    if homodyne:
        vr = np.abs(vr)
    snr = rng.uniform(0.02, 1.0, vr.shape)
    snr[rng.random(vr.shape) < 0.05] = 0.001
    start = np.datetime64("2024-05-01T00:00", "ns")
    times = start + (np.arange(n) * (120.0 / n_rays) * 1e9).astype("timedelta64[ns]")
    return xr.Dataset(
        {"radial_velocity": (("ray", "range"), vr), "snr": (("ray", "range"), snr)},
        coords={
            "time": ("ray", times),
            "azimuth": ("ray", az),
            "elevation": ("ray", el),
            "scan": ("ray", np.repeat(np.arange(n_scans), n_rays)),
            "range": ("range", ranges),
        },
        attrs={
            "homodyne": int(homodyne),
            "velocity_resolution_m_s": 0.0382,
            "reference_direction_deg": 300.0,  # the true wind is from ~300 deg
        },
    ), (u, v)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", type=int, default=720)
    parser.add_argument("--rays", type=int, default=24)
    parser.add_argument("--gates", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--homodyne", action="store_true", help="|V_r| only (ZephIR-like)")
    args = parser.parse_args()
    ds, (u_true, v_true) = synthetic_day(args.scans, args.rays, args.gates, homodyne=args.homodyne)
    qc_times, vad_times = [], []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        screened = screen_radial_velocity(ds, snr_min=0.008, outlier_threshold=4.0)
        t1 = time.perf_counter()
        wind = fit_vad(screened, min_rays=6, max_gap_deg=120.0)
        t2 = time.perf_counter()
        qc_times.append(t1 - t0)
        vad_times.append(t2 - t1)
    tracemalloc.start()
    screened = screen_radial_velocity(ds, snr_min=0.008, outlier_threshold=4.0)
    wind = fit_vad(screened, min_rays=6, max_gap_deg=120.0)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    good = wind["qc_flag"].values == 0
    used = float(np.mean(wind["n_rays"].values[good]))
    du = (wind["u"].values - u_true)[good]
    dv = (wind["v"].values - v_true)[good]
    print(
        f"input: {'homodyne ' if args.homodyne else ''}"
        f"{args.scans} scans x {args.rays} rays x {args.gates} gates "
        f"({ds['radial_velocity'].size / 1e6:.2f} M radial velocities)"
    )
    print(f"qc  (screen_radial_velocity): best {min(qc_times):.2f} s of {args.repeat}")
    print(f"vad (fit_vad):                best {min(vad_times):.2f} s of {args.repeat}")
    print(f"qc + vad:                     {min(qc_times) + min(vad_times):.2f} s")
    print(f"peak traced memory (qc + vad): {peak / 2**20:.0f} MiB")
    flags = screened["qc_flag_radial"].values
    print(f"flagged: low SNR {np.mean(flags & 1 > 0):.3f}, outlier {np.mean(flags & 2 > 0):.3f}")
    print(
        f"good fits: {good.mean():.4f}; rms error u {np.sqrt(np.mean(du**2)):.4f} m/s, "
        f"v {np.sqrt(np.mean(dv**2)):.4f} m/s "
        f"(seed 002 for {used:.1f} rays, sigma 0.3, phi 60: "
        f"{float(rms_error_full_circle(round(used), 60.0, 0.3)[0]):.3f})"
    )


if __name__ == "__main__":
    main()
