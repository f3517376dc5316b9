#!/usr/bin/env python3
"""Where the spring fit through the motor goes wrong on one plant: the
simulator's ground truth laid beside the fit (docs/force.md, "Where the
spring fit's remaining error comes from (stop 77)").

Runs the seed's calibration on a plant with every column of the log,

    host-sim simulate --scenario jae-ident --plant P.toml [--config R.toml]
        --out DIR/j.csv

and fits, on the same sweeps as `identify --procedure jae` (both sliders
moving one way faster than 0.2 mm/s, counted after 60 µm and three DOB
time constants), each sweep's means out, everything through the DOB's
`Q`:

* the DOB's cable-1 tension (`tension1_hat_n`) on `x2`, `x2'` and slider
  1's stick (the per-tick fit: what `identify` writes, to the smoothing
  of this script's central differences), and with the pin's stick
  (grating 2 lagging its smoothed speed, as slider 1's) as a fourth
  column;
* the true spring force, cable 2's and cable 1's tension on the same
  columns: where cable 1's slope is not the spring's, the tension the
  motor sees changes by more than the spring over a sweep;
* the pin's force, cable 1 less cable 2, in the sweep's direction, and the
  share of ticks the pin stands still, by fifth of the sweep (mean over
  the sweeps).

    python3 scripts/spring-trace.py --plant p37.toml --rate 1000 --out /tmp/tr

(`p37.toml`: seed 37 of `scripts/spring-heldout.py`, which writes it as
`OUT/p37.toml`.) A few seconds after `cargo build --release -p host-sim`;
numpy needed.
"""

import argparse
import math
import os
import subprocess
import sys
import tomllib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import logcsv  # noqa: E402

HOST_SIM = os.path.join(os.path.dirname(__file__), "..", "target", "release", "host-sim")
# identify's constants (host-sim/src/ident/spring.rs, joint.rs): the sweep
# threshold (the tension model's switching speed), the travel before a
# sweep's ticks count, the central differences' half window.
SWITCH_M_S = 2e-4
MIN_TRAVEL_M = 60e-6
HALF_WINDOW_S = 0.005
GRATING_M = 1e-6
COLS = ["x1_m", "x2_m", "x2_vel_m_s", "tension1_hat_n", "fs_true_n", "fw2_true_n",
        "fw1_true_n", "theta_true_rad"]


def low_pass(u, pole):
    """The DOB's `Q`: a first-order low-pass started at the first value."""
    u = np.asarray(u, dtype=float)
    y = np.empty_like(u)
    s = u[0]
    for i, v in enumerate(u):
        s = pole * s + (1.0 - pole) * v
        y[i] = s
    return y


def central(x, half, period_s):
    v = np.full(len(x), np.nan)
    v[half:-half] = (x[2 * half:] - x[:-2 * half]) / (2 * half * period_s)
    return v


def stuck(x, w, period_s):
    """The sweep's sign where the grating advanced less than one count over
    the ticks its smoothed speed needs for three, else 0."""
    out = np.zeros(len(x))
    for k, v in enumerate(w):
        if not np.isfinite(v) or v == 0.0:
            continue
        ticks = math.ceil(3 * GRATING_M / (abs(v) * period_s))
        if ticks <= k and (x[k] - x[k - ticks]) * np.sign(v) < GRATING_M:
            out[k] = np.sign(v)
    return out


def sweeps(x1, x2, w1, w2, period_s, settle_s):
    found, cur, start = [], [], None
    for k in range(len(x1)):
        d = np.sign(w2[k])
        sliding = (np.isfinite(w1[k]) and np.isfinite(w2[k]) and abs(w1[k]) > SWITCH_M_S
                   and abs(w2[k]) > SWITCH_M_S and np.sign(w1[k]) == d)
        if start is not None and sliding and start[1] == d:
            k0 = start[0]
            if (abs(x1[k] - x1[k0]) >= MIN_TRAVEL_M and abs(x2[k] - x2[k0]) >= MIN_TRAVEL_M
                    and (k - k0) * period_s >= settle_s):
                cur.append(k)
        else:
            if len(cur) // 3 >= 10:
                found.append(np.array(cur))
            cur, start = [], ((k, d) if sliding else None)
    if len(cur) // 3 >= 10:
        found.append(np.array(cur))
    return found


def fit(sw, cols, y):
    """Least squares on every sweep's ticks, each sweep's means out."""
    xs = [cols[i] - cols[i].mean(axis=0) for i in sw]
    ys = [y[i] - y[i].mean() for i in sw]
    b, *_ = np.linalg.lstsq(np.vstack(xs), np.concatenate(ys), rcond=None)
    return b


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--plant", required=True)
    ap.add_argument("--rate", type=float, default=2000.0, help="control rate, Hz")
    ap.add_argument("--dob-cutoff-rad-s", type=float, default=2 * math.pi * 10,
                    help="the DOB's Q (dob.cutoff_rad_s)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    log = os.path.join(a.out, "j.csv")
    cfg = []
    if a.rate != 2000.0:
        path = os.path.join(a.out, "rate.toml")
        with open(path, "w") as f:
            f.write(f"control_rate_hz = {a.rate:.1f}\n")
        cfg = ["--config", path]
    subprocess.run([HOST_SIM, "simulate", "--scenario", "jae-ident", "--plant", a.plant, *cfg,
                    "--out", log], check=True, capture_output=True)
    cols = logcsv.read_columns(log, COLS, min_rows=2)
    col = lambda n: np.array(cols[n])  # noqa: E731
    period_s = 1.0 / a.rate
    half = max(1, round(HALF_WINDOW_S / period_s))
    x1, x2, v2 = col("x1_m"), col("x2_m"), col("x2_vel_m_s")
    w1, w2 = central(x1, half, period_s), central(x2, half, period_s)
    pole = math.exp(-a.dob_cutoff_rad_s * period_s)
    sw = sweeps(x1, x2, w1, w2, period_s, 3.0 / a.dob_cutoff_rad_s)
    s1, s2 = stuck(x1, w1, period_s), stuck(x2, w2, period_s)
    q = np.column_stack([low_pass(c, pole) for c in (x2, v2, s1, s2)])
    with open(a.plant, "rb") as f:
        plant = tomllib.load(f)
    k_plant = plant.get("spring", {}).get("stiffness_n_m", 656.6)
    print(f"{len(sw)} sweeps; the plant's spring {k_plant:.0f} N/m")
    y = col("tension1_hat_n")
    base = fit(sw, q[:, :3], y)[0]
    both = fit(sw, q, y)[0]
    print(f"DOB tension on x2, x2', slider 1's stick: {base:.0f} N/m ({100 * (base / k_plant - 1):+.1f} %); "
          f"the pin's stick a fourth column: {both:.0f} N/m ({100 * (both / k_plant - 1):+.1f} %)")
    for name in ["fs_true_n", "fw2_true_n", "fw1_true_n"]:
        k = fit(sw, q[:, :3], low_pass(col(name), pole))[0]
        print(f"true {name} on the same columns: {k:.0f} N/m ({100 * (k / k_plant - 1):+.1f} %)")
    pin = col("fw1_true_n") - col("fw2_true_n")
    theta = col("theta_true_rad")
    still = np.concatenate([[False], np.abs(np.diff(theta)) < 1e-12])
    fifths = np.zeros((2, 5))
    for idx in sw:
        sign = np.sign(x2[idx[-1]] - x2[idx[0]])
        parts = np.array_split(idx, 5)
        fifths[0] += [sign * pin[p].mean() for p in parts]
        fifths[1] += [still[p].mean() for p in parts]
    fifths /= len(sw)
    print("the pin's force in the sweep's direction by fifth, N: "
          + " ".join(f"{v:.3f}" for v in fifths[0]))
    print("share of ticks the pin stands still by fifth: "
          + " ".join(f"{v:.2f}" for v in fifths[1]))


if __name__ == "__main__":
    main()
