"""Accuracy of the turbulence retrieval on the seed-000 cw simulation (prints figures).

Simulates ``--blocks`` independent blocks of N = 10 scans of the virtual cw lidar of
Banakh et al. (1999) (``configs/banakh1999.toml``: lambda = 10.6 um, a0 = 7.5 cm,
phi = 30 deg, T = 7 s, the paper's six heights), runs qc -> vad -> structure -> epsilon
(model "exponential", l = 3) and prints, per height, the mean ratio estimate/truth and
the relative RMS error of epsilon, epsilon_fit, sigma_V^2 and L_V, and the mean sigma_e.

    python benchmarks/bench_cw_epsilon_bias.py --blocks 12            # heterodyne
    python benchmarks/bench_cw_epsilon_bias.py --blocks 12 --homodyne
    python benchmarks/bench_cw_epsilon_bias.py --blocks 12 --exact   # true V_D
    python benchmarks/bench_cw_epsilon_bias.py --blocks 12 --no-noise  # cw fit, no sigma_e

``--exact`` replaces the centroid estimates by the simulator's exact probe-averaged
V_D (signed, heterodyne processing): what remains is the retrieval's own error; the
difference to the default run is what the centroid estimation adds.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time

import numpy as np
import xarray as xr

from cwproc.config import load_config
from cwproc.physics.dissipation import epsilon_from_integral_scale
from cwproc.pipeline import probe_from_config
from cwproc.sim.cw import simulate_cw_scans
from cwproc.sim.montecarlo import lidar_from_config
from cwproc.stages import epsilon, qc, structure, vad
from cwproc.stages.epsilon.cw_exact import NOISE_WINDOW_BLOCKS

NAMES = ("epsilon", "epsilon_fit", "velocity_variance", "integral_scale", "noise_std")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=12)
    parser.add_argument("--homodyne", action="store_true")
    parser.add_argument("--seed", type=int, default=100)
    parser.add_argument("--exact", action="store_true", help="use the exact V_D")
    parser.add_argument("--no-noise", action="store_true", help="cw fit without the noise term")
    parser.add_argument(
        "--noise-window",
        type=int,
        default=NOISE_WINDOW_BLOCKS,
        help="blocks over which the cw noise is pooled (1: each block its own)",
    )
    parser.add_argument(
        "--max-lag-deg", type=float, default=None, help="largest lag (deg); default: config"
    )
    args = parser.parse_args()
    cfg = load_config("banakh1999")
    sim = cfg.simulation
    lidar = dataclasses.replace(
        lidar_from_config(sim, cfg.instrument.wavelength_m, cfg.instrument.beam_radius_m),
        homodyne=args.homodyne,
    )
    heights = np.array(sim.heights_m)
    sigma2 = np.array(sim.sigma_v_m_s) ** 2
    scale = np.array(sim.outer_scale_m)
    truth = {
        "epsilon": epsilon_from_integral_scale(sigma2, scale, "exponential"),
        "epsilon_fit": epsilon_from_integral_scale(sigma2, scale, "exponential"),
        "velocity_variance": sigma2,
        "integral_scale": scale,
    }
    probe = probe_from_config(cfg.instrument)
    blocks = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as cache:
        for b in range(args.blocks):  # independent blocks, 10 minutes apart
            ds, exact = simulate_cw_scans(
                np.random.default_rng(args.seed + b),
                lidar,
                heights_m=heights,
                wind_speed=np.array(sim.wind_speed_m_s),
                wind_direction_deg=sim.wind_direction_deg,
                sigma2=sigma2,
                outer_scale_m=scale,
                n_scans=cfg.turbulence.n_scans,
                start=np.datetime64("2024-01-01T00:00") + b * np.timedelta64(600, "s"),
            )
            if args.exact:
                ds = ds.assign(radial_velocity=(("ray", "range"), exact))
                ds.attrs["homodyne"] = 0
            scr = qc.screen_radial_velocity(
                ds, snr_min=cfg.qc.snr_min, outlier_threshold=cfg.qc.outlier_threshold
            )
            wind = vad.fit_vad(
                scr,
                min_rays=cfg.vad.min_rays,
                max_gap_deg=cfg.vad.max_gap_deg,
                reference_direction_deg=sim.wind_direction_deg,
            )
            blocks.append(
                structure.azimuth_structure_function(
                    scr,
                    wind,
                    n_scans=cfg.turbulence.n_scans,
                    max_lag_deg=args.max_lag_deg or cfg.turbulence.max_lag_deg,
                )
            )
        turb = epsilon.estimate_epsilon(  # all blocks at once, as retrieve does for a day
            xr.concat(blocks, "time"),
            probe=probe,
            lag_number=cfg.turbulence.lag_number,
            model=cfg.turbulence.model,
            table_options={"cache_dir": cache},
            fit_noise=not args.no_noise,
            noise_window_blocks=args.noise_window,
        )
    out = {k: turb[k].values for k in NAMES}
    elapsed = time.perf_counter() - t0
    kind = "homodyne" if args.homodyne else "heterodyne"
    kind = "exact V_D" if args.exact else kind
    print(f"seed-000 cw simulation, {kind}, {args.blocks} blocks of N = 10 ({elapsed:.0f} s)")
    print("height (m)          " + " ".join(f"{h:7.0f}" for h in heights))
    for k, t in truth.items():
        ratio = np.array(out[k]) / t
        mean = np.nanmean(ratio, axis=0)
        rms = np.sqrt(np.nanmean((ratio - 1) ** 2, axis=0))
        print(f"{k:18s} mean " + " ".join(f"{x:7.3f}" for x in mean))
        print(f"{'':18s} rms  " + " ".join(f"{x:7.3f}" for x in rms))
        median = np.nanmedian(ratio, axis=0)
        print(f"{'':18s} med  " + " ".join(f"{x:7.3f}" for x in median))
    noise = np.nanmean(np.array(out["noise_std"]), axis=0)
    print(f"{'noise_std (m/s)':18s} mean " + " ".join(f"{x:7.3f}" for x in noise))


if __name__ == "__main__":
    main()
