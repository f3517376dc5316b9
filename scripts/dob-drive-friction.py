#!/usr/bin/env python3
"""How much of the DOB's force error on a simulated loading log is the
drive's own Coulomb friction (README, "Cable 0's stiffness for the slack
check", stop 55; not in the core's model).

The DOB reads the motor's torque balance, so its cable-1 tension carries
the drive's Coulomb friction `tau_c z_i / r_m` with the sign of the motor's
speed. Model C has no term of its own for it: `identify` fits it inside
`f_sc1`, which turns with slider 1's held sign. While the hold's motor
turns back and forth inside the rope's stretch and slider 1 stands still,
the two signs differ and the DOB's tip force is off by
`tau_c z_i / r_m (sgn phi' - s1) r / l_e` through `Q`. This script
subtracts that share (the motor's sign held at its last non-zero speed,
slider 1's with the tension model's switching speed, both through the
DOB's `Q`) and prints, per phase of the log, the DOB's error
(`f_ext_hat_n - f_ext_n`) rms before and after, and the share of rows in
which the two held signs differ.

    host-sim identify --procedure all --log bm=bm.csv jae=id.csv \\
        tension=tension.csv --config c.toml --config-out identified.toml \\
        --json id.json
    host-sim simulate --scenario loading --config identified.toml \\
        --out loading.csv
    python3 scripts/dob-drive-friction.py loading.csv identified.toml id.json

`tau_c` is `bm.coulomb_nm` of the identification's JSON (the no-load
motor run's Coulomb term; the script stops if it was not kept). Needs
numpy; the log and configuration readers are `logcsv.py` and
`configkeys.py`, beside this script.
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import configkeys  # noqa: E402
import logcsv  # noqa: E402

COLS = ["phase", "phi_vel_rad_s", "x1_vel_m_s", "f_ext_n", "f_ext_hat_n"]


def held_sign(v, switch):
    """The sign of `v` while `|v| > switch`, else the last one (0 at first)."""
    out, h = np.empty_like(v), 0.0
    for k, x in enumerate(v):
        if x > switch:
            h = 1.0
        elif x < -switch:
            h = -1.0
        out[k] = h
    return out


def low_pass(u, pole):
    """The core's `LowPass1` from the first value."""
    out, y = np.empty_like(u), u[0]
    for k, x in enumerate(u):
        y = pole * y + (1.0 - pole) * x
        out[k] = y
    return out


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    log, config, ident = sys.argv[1:]
    text = open(config).read()
    value = lambda key: configkeys.value(config, text, key)  # noqa: E731
    try:
        tau_c = json.load(open(ident))["bm"]["coulomb_nm"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        sys.exit(f"{ident}: no bm.coulomb_nm ({e})")
    if tau_c is None:
        sys.exit(f"{ident}: bm.coulomb_nm is null (the drive's Coulomb term was not kept)")
    d = {c: np.array(v) for c, v in logcsv.read_columns(log, COLS, min_rows=2).items()}
    pole = np.exp(-value("cutoff_rad_s") / value("control_rate_hz"))
    tension_per_torque = value("gear_ratio") / value("rope_wheel_radius_m")
    tip_per_tension = value("pulley_radius_m") / value("gripper_length_m")
    switch = value("sign_switch_x1_m_s")
    s_phi = held_sign(d["phi_vel_rad_s"], 0.0)
    s_x1 = held_sign(d["x1_vel_m_s"], switch)
    share = tau_c * tension_per_torque * tip_per_tension * (
        low_pass(s_phi, pole) - low_pass(s_x1, pole)
    )
    err = d["f_ext_hat_n"] - d["f_ext_n"]
    apart = s_phi != s_x1
    print(
        f"{log}: tau_c {tau_c:.4g} N·m, {tau_c * tension_per_torque:.2f} N at the rope, "
        f"{tau_c * tension_per_torque * tip_per_tension:.3f} N at the tip"
    )
    print("  phase      rows   DOB error rms   less the drive's share   signs differ")
    for p in np.unique(d["phase"]):
        m = d["phase"] == p
        rms = lambda e: np.sqrt(np.mean(e[m] ** 2))  # noqa: E731
        print(
            f"  {p:5.0f} {m.sum():9d} {rms(err):12.3f} N {rms(err - share):20.3f} N "
            f"{100.0 * np.mean(apart[m]):12.1f} %"
        )


if __name__ == "__main__":
    main()
