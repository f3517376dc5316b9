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
  constant per stretch), and
* over the same stretches with the DOB's low-pass `Q` undone row by row
  and a 5 ms moving mean on both sides, as `identify` reads it (the
  filtered reading lags the rising tension and still carries the
  friction's change at the reversal just before each stretch). `Q`'s
  cut-off is `dob.cutoff_rad_s` from `--config`, else the default 10 Hz;
  the log must have a row every control tick (as `simulate` writes).

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

Standard library only (the log and configuration readers are `logcsv.py`
and `configkeys.py`, beside this script). The rope wheel radius and gear ratio come from the
plant file when given, else the datasheet's (6 mm, 35).
"""

import argparse
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import configkeys  # noqa: E402
import logcsv  # noqa: E402

MIN_STRETCH_S = 0.01
STILL_X1_M_S = 2e-5
TURNING_RAD_S = 0.3
SKIP_ROWS = 400
MEAN_S = 0.005
DEFAULT_DOB_CUTOFF_RAD_S = 2.0 * math.pi * 10.0


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


def moving_means(rows, width):
    """Each stretch's moving means over `width` rows, wholly inside it."""
    return [
        tuple(sum(r[c] for r in rows[i : i + width]) / width for c in range(len(rows[0])))
        for i in range(len(rows) - width + 1)
    ]


def study(path, m_per_rad, dob_cutoff_rad_s):
    """The slopes, and the log's columns (`check_2_margin` reads them too)."""
    need = ["t_s", "phi_rad", "x1_m", "tension1_hat_n", "x1_vel_m_s", "phi_vel_rad_s"]
    col = logcsv.read_columns(path, need, optional=["f1_true_n", "tension1_stretch_n"])
    truth = "f1_true_n" in col
    t = col["t_s"]
    if len(t) < SKIP_ROWS + 2:
        sys.exit(f"{path}: {len(t)} rows, fewer than the {SKIP_ROWS + 2} the study skips and needs")
    rate_hz = (len(t) - 1) / (t[-1] - t[0])
    pole = math.exp(-dob_cutoff_rad_s / rate_hz)
    every, stretches, current, last_sign, last_row = [], [], None, 0, -2
    for n in range(SKIP_ROWS, len(col["phi_rad"])):
        e = col["phi_rad"][n] * m_per_rad - col["x1_m"][n]
        reading = col["tension1_hat_n"][n]
        undone = (reading - pole * col["tension1_hat_n"][n - 1]) / (1.0 - pole)
        true_n = col["f1_true_n"][n] if truth else float("nan")
        x1_vel = col["x1_vel_m_s"][n]
        phi_vel = col["phi_vel_rad_s"][n]
        every.append((e, reading, true_n))
        sign = 1 if phi_vel > 0 else -1
        if abs(x1_vel) < STILL_X1_M_S and abs(phi_vel) > TURNING_RAD_S:
            if current is not None and sign == last_sign and n == last_row + 1:
                current.append((e, reading, true_n, undone))
            else:
                current = [(e, reading, true_n, undone)]
                stretches.append(current)
            last_sign, last_row = sign, n
        else:
            current = None
    stretches = [s for s in stretches if (len(s) - 1) / rate_hz >= MIN_STRETCH_S]
    rows = sum(len(s) for s in stretches)
    width = max(1, round(MEAN_S * rate_hz))
    means = [moving_means(s, width) for s in stretches if len(s) > width]
    out = {
        "all_rows_reading": slope([(e, r) for e, r, _ in every]),
        "stretches": len(stretches),
        "stretch_rows": rows,
        "stretches_reading": fixed_effects_slope(stretches, 1) if rows else float("nan"),
        "stretches_undone": fixed_effects_slope(means, 3) if means else float("nan"),
        "rate_hz": rate_hz,
        "columns": col,
    }
    if truth:
        out["all_rows_truth"] = slope([(e, t) for e, _, t in every])
        out["stretches_truth"] = fixed_effects_slope(stretches, 2) if rows else float("nan")
    return out


def read_loading(path):
    """The loading log's columns check 2's replay needs."""
    need = ["t_s", "phi_rad", "x1_m", "tension1_stretch_n", "f1_true_n", "fault_code"]
    # An empty `fault_code` cell (NaN) is no fault, as 0 is.
    return logcsv.read_columns(path, need, allow_empty=["fault_code"])


def replay_check_2(col, config_value, stiffness_n_m, m_per_rad):
    """(first slack time, (latch time, true tension) or None) on a loading
    log's columns (`read_loading`); `config_value(key)` reads the
    configuration."""
    f_sc1 = abs(config_value("f_sc1_n"))
    limit = config_value("min_tension_fraction") * config_value("preload_n")
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


def check_2_margin(col, config_value):
    """(least `T_1 + 2 f_sc1 - T_0`, largest `T_0 / (T_1 + 2 f_sc1 + limit)`)
    over a simulated log's columns (`f1_true_n`), or None without that
    column; `config_value(key)` reads the configuration."""
    f_sc1 = abs(config_value("f_sc1_n"))
    limit = config_value("min_tension_fraction") * config_value("preload_n")
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
    # Read once: a loading log runs to hundreds of megabytes.
    loading = read_loading(a.loading) if a.loading else None
    cutoff = DEFAULT_DOB_CUTOFF_RAD_S
    if a.config:
        config_text = open(a.config).read()
        config_value = lambda key: configkeys.value(a.config, config_text, key)  # noqa: E731
        cutoff = config_value("cutoff_rad_s")
    for path in a.logs:
        s = study(path, radius_m / gear, cutoff)
        line = (
            f"{path}: all rows {s['all_rows_reading']:.0f} N/m; "
            f"{s['stretches']} stretches ({s['stretch_rows']} rows) {s['stretches_reading']:.0f} N/m, "
            f"{s['stretches_undone']:.0f} N/m with Q undone ({cutoff:.1f} rad/s at "
            f"{s['rate_hz']:.0f} Hz)"
        )
        if "stretches_truth" in s:
            line += f"; on the true tension {s['all_rows_truth']:.0f} / {s['stretches_truth']:.0f} N/m"
        if k0:
            line += (
                f"; rope {k0:.0f} N/m, stretches / rope {s['stretches_reading'] / k0:.2f}, "
                f"with Q undone {s['stretches_undone'] / k0:.2f}"
            )
        print(line)
        if a.config:
            margin = check_2_margin(s["columns"], config_value)
            if margin and margin[1] > 0:
                print(
                    f"  check 2's margin on this log: the rope's true tension at least {margin[0]:.2f} N "
                    f"below T_1 + 2 f_sc1, at most {margin[1]:.3f} of T_1 + 2 f_sc1 + limit "
                    f"(a stiffness up to {1.0 / margin[1]:.2f} times the rope's keeps the floor under e_0)"
                )
        if a.loading:
            k1 = config_value("cable1_n_m")
            scaled = s["stretches_undone"] * a.scale
            for name, k in (("cable 1's", k1), (f"the stretches' x {a.scale:g}", scaled)):
                if not k > 0:
                    print(f"  check 2 with {name} stiffness: none read")
                    continue
                slack, latch = replay_check_2(loading, config_value, k, radius_m / gear)
                when = f"latches at {latch[0]:.3f} s" if latch else "does not latch"
                first = f"rope first slack at {slack:.3f} s" if slack is not None else "rope never slack"
                print(f"  check 2 with {name} stiffness ({k:.0f} N/m): {when}; {first}")


if __name__ == "__main__":
    main()
