#!/usr/bin/env python3
"""Cable 0's stiffness read off a `tension-ident` log: the study behind
`identify`'s `stretch.cable0_n_m` (`host-sim/src/ident/cable0.rs`, which
reads it from the replayed log the same way) and the cable-0 slack
check's reach. README, "Cable 0's stiffness for the slack check".

For each log, the slope of the motor's tension reading (`tension1_hat_n`)
against cable 0's measured elongation `e = phi r_m / z_i - x1`:

* over every row (the motor's friction rides on the reading, and the
  slope comes out 1.4 to 1.9 times the rope's), and
* over the stretches where slider 1 stands still (|x1'| below 20 um/s)
  and the motor turns one way (|phi'| above 0.3 rad/s), each stretch with
  an offset of its own (a fixed-effects fit: the motor's friction is one
  constant per stretch).

With the simulator's columns (`f1_true_n`, the rope's true tension) it
prints the same slopes on the truth, and with the plant file the rope's
stiffness, for comparison.

    host-sim simulate --scenario tension-ident --config V/config.toml \\
        --plant V/plant.toml --out t.csv
    python3 scripts/cable0-stiffness.py t.csv --plant V/plant.toml

With `--config C.toml` (the configuration the log ran with) it prints
check 2's margin on the log: how far the rope's true tension stayed below
`T_1 + 2 f_sc1`, and the largest share of `T_1 + 2 f_sc1 + limit` it
reached. With `--loading L.csv` as well it then replays the cable-0 check 2
of `src/control/controller.rs` offline on a loading log (the floor
`max(e - (T_1 + 2 f_sc1 + limit) / K)` with `T_1` the log's
`tension1_stretch_n`), once with cable 1's stiffness as the firmware has
it and once with the stiffness read from the stretches (and with
`--scale`, that times a factor), and prints when each would have latched
against when the rope first went slack (`f1_true_n` at zero).

    python3 scripts/cable0-stiffness.py t.csv --plant V/plant.toml \\
        --loading l.csv --config V/config.toml

Standard library only (the log reader is `logcsv.py`, beside this
script). The rope wheel radius and gear ratio come from the
plant file when given, else the datasheet's (6 mm, 35).
"""

import argparse
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import logcsv  # noqa: E402

MIN_STRETCH_ROWS = 20
STILL_X1_M_S = 2e-5
TURNING_RAD_S = 0.3
SKIP_ROWS = 400


def plant_value(text, table, key):
    m = re.search(r"\[" + table + r"\][^\[]*?\n" + key + r" = ([0-9.eE+-]+)", text)
    return float(m.group(1)) if m else None


def slope(pairs):
    """Least-squares slope of y on x with an intercept; pairs (x, y)."""
    n = len(pairs)
    if n < 2:
        return float("nan")
    mx = sum(x for x, _ in pairs) / n
    my = sum(y for _, y in pairs) / n
    sxx = sum((x - mx) ** 2 for x, _ in pairs)
    sxy = sum((x - mx) * (y - my) for x, y in pairs)
    return sxy / sxx if sxx > 0 else float("nan")


def fixed_effects_slope(stretches, col):
    """Slope shared by all stretches, each with its own offset."""
    num = den = 0.0
    for rows in stretches:
        me = sum(r[0] for r in rows) / len(rows)
        my = sum(r[col] for r in rows) / len(rows)
        for r in rows:
            num += (r[0] - me) * (r[col] - my)
            den += (r[0] - me) ** 2
    return num / den if den > 0 else float("nan")


def study(path, m_per_rad):
    need = ["phi_rad", "x1_m", "tension1_hat_n", "x1_vel_m_s", "phi_vel_rad_s"]
    col = logcsv.read_columns(path, need, optional=["f1_true_n"])
    truth = "f1_true_n" in col
    every, stretches, current, last_sign, last_row = [], [], None, 0, -2
    for n in range(SKIP_ROWS, len(col["phi_rad"])):
        e = col["phi_rad"][n] * m_per_rad - col["x1_m"][n]
        reading = col["tension1_hat_n"][n]
        true_n = col["f1_true_n"][n] if truth else float("nan")
        x1_vel = col["x1_vel_m_s"][n]
        phi_vel = col["phi_vel_rad_s"][n]
        every.append((e, reading, true_n))
        sign = 1 if phi_vel > 0 else -1
        if abs(x1_vel) < STILL_X1_M_S and abs(phi_vel) > TURNING_RAD_S:
            if current is not None and sign == last_sign and n == last_row + 1:
                current.append((e, reading, true_n))
            else:
                current = [(e, reading, true_n)]
                stretches.append(current)
            last_sign, last_row = sign, n
        else:
            current = None
    stretches = [s for s in stretches if len(s) >= MIN_STRETCH_ROWS]
    rows = sum(len(s) for s in stretches)
    out = {
        "all_rows_reading": slope([(e, r) for e, r, _ in every]),
        "stretches": len(stretches),
        "stretch_rows": rows,
        "stretches_reading": fixed_effects_slope(stretches, 1) if rows else float("nan"),
    }
    if truth:
        out["all_rows_truth"] = slope([(e, t) for e, _, t in every])
        out["stretches_truth"] = fixed_effects_slope(stretches, 2) if rows else float("nan")
    return out


def config_value(text, key):
    m = re.search(r"\n" + key + r" = ([0-9.eE+-]+)", text)
    if not m:
        sys.exit(f"configuration: no {key}")
    return float(m.group(1))


def replay_check_2(path, config_text, stiffness_n_m, m_per_rad):
    """(first slack time, (latch time, true tension) or None) on a loading log."""
    f_sc1 = abs(config_value(config_text, "f_sc1_n"))
    limit = config_value(config_text, "min_tension_fraction") * config_value(config_text, "preload_n")
    need = ["t_s", "phi_rad", "x1_m", "tension1_stretch_n", "f1_true_n", "fault_code"]
    # An empty `fault_code` cell (NaN) is no fault, as 0 is.
    col = logcsv.read_columns(path, need, allow_empty=["fault_code"])
    floor, slack, latch = -math.inf, None, None
    for n in range(len(col["t_s"])):
        t = col["t_s"][n]
        e = col["phi_rad"][n] * m_per_rad - col["x1_m"][n]
        t1 = max(0.0, col["tension1_stretch_n"][n])
        true_n = col["f1_true_n"][n]
        floor = max(floor, e - (t1 + 2.0 * f_sc1 + limit) / stiffness_n_m)
        if slack is None and true_n <= 0.0:
            slack = t
        if latch is None and e < floor:
            latch = (t, true_n)
        fault = col["fault_code"][n]
        if fault == fault and fault != 0:
            break
    return slack, latch


def check_2_margin(path, config_text):
    """(least `T_1 + 2 f_sc1 - T_0`, largest `T_0 / (T_1 + 2 f_sc1 + limit)`)
    over a simulated log (`f1_true_n`), or None without that column."""
    f_sc1 = abs(config_value(config_text, "f_sc1_n"))
    limit = config_value(config_text, "min_tension_fraction") * config_value(config_text, "preload_n")
    col = logcsv.read_columns(path, [], optional=["f1_true_n", "tension1_stretch_n"])
    if "f1_true_n" not in col or "tension1_stretch_n" not in col:
        return None
    least, largest = math.inf, 0.0
    for n in range(SKIP_ROWS, len(col["f1_true_n"])):
        t0 = col["f1_true_n"][n]
        bound = max(0.0, col["tension1_stretch_n"][n]) + 2.0 * f_sc1
        least = min(least, bound - t0)
        largest = max(largest, t0 / (bound + limit))
    return least, largest


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs", nargs="+", help="tension-ident CSV logs")
    ap.add_argument("--plant", help="plant.toml (the rope's stiffness, its wheel and gear)")
    ap.add_argument("--loading", help="a loading log to replay check 2 on")
    ap.add_argument("--config", help="the configuration the loading log ran with")
    ap.add_argument("--scale", type=float, default=1.0, help="factor on the stretches' stiffness")
    a = ap.parse_args()
    if a.loading and not a.config:
        sys.exit("--loading needs --config")
    k0 = None
    radius_m, gear = 0.006, 35.0
    if a.plant:
        text = open(a.plant).read()
        k0 = plant_value(text, "cable0", "stiffness_n_m")
        radius_m = plant_value(text, "motor", "rope_wheel_radius_m") or radius_m
        gear = plant_value(text, "motor", "gear_ratio") or gear
    for path in a.logs:
        s = study(path, radius_m / gear)
        line = (
            f"{path}: all rows {s['all_rows_reading']:.0f} N/m; "
            f"{s['stretches']} stretches ({s['stretch_rows']} rows) {s['stretches_reading']:.0f} N/m"
        )
        if "stretches_truth" in s:
            line += f"; on the true tension {s['all_rows_truth']:.0f} / {s['stretches_truth']:.0f} N/m"
        if k0:
            line += f"; rope {k0:.0f} N/m, stretches / rope {s['stretches_reading'] / k0:.2f}"
        print(line)
        if a.config:
            config_text = open(a.config).read()
            margin = check_2_margin(path, config_text)
            if margin and margin[1] > 0:
                print(
                    f"  check 2's margin on this log: the rope's true tension at least {margin[0]:.2f} N "
                    f"below T_1 + 2 f_sc1, at most {margin[1]:.3f} of T_1 + 2 f_sc1 + limit "
                    f"(a stiffness up to {1.0 / margin[1]:.2f} times the rope's keeps the floor under e_0)"
                )
        if a.loading:
            k1 = config_value(config_text, "cable1_n_m")
            scaled = s["stretches_reading"] * a.scale
            for name, k in (("cable 1's", k1), (f"the stretches' x {a.scale:g}", scaled)):
                if not k > 0:
                    print(f"  check 2 with {name} stiffness: none read")
                    continue
                slack, latch = replay_check_2(a.loading, config_text, k, radius_m / gear)
                when = f"latches at {latch[0]:.3f} s" if latch else "does not latch"
                first = f"rope first slack at {slack:.3f} s" if slack is not None else "rope never slack"
                print(f"  check 2 with {name} stiffness ({k:.0f} N/m): {when}; {first}")


if __name__ == "__main__":
    main()
