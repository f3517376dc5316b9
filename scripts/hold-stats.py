#!/usr/bin/env python3
"""Statistics of simulated loading holds (`host-sim simulate --scenario
loading ... --out hold.csv`), one line for a set of holds:

    least_cov   least share of a hold's settled samples (a second or more
                after the load last changed, up to a latched fault) whose
                load lies inside the bound, %
    holds<99.5  holds whose share is under 99.5 %
    worst>1N    worst accuracy 100 (1 - |mean fused - load| / load) over the
                holds' settled samples under a load above 0.5 N, %; mean>1N
                their mean; worst0.3 the same under loads up to 0.5 N
    noload      the largest |fused estimate| over the second half of each
                no-load region (`phase` 3, before loading and after
                unloading), N: the static no-load error as the report
                counts it
    faults      holds that latched a fault
    tip_pp      the largest peak-to-peak of the plant's joint angle
                (`theta_true_rad`) over a hold's settled loaded samples, deg

    python3 scripts/hold-stats.py holds/*.csv

Used by scripts/weights-heldout.sh and scripts/heldout-chain.py.
"""

import csv
import math
import sys


def stats(paths):
    """The figures above for the hold CSVs `paths`, as a dict."""
    covs, big, small, faults, tip_pp, noload_n = [], [], [], 0, 0.0, 0.0
    for path in paths:
        last, since, n, inside, loaded = None, 0.0, 0, 0, {}
        lo_rad, hi_rad = math.inf, -math.inf
        region = []  # the current no-load region's |fused|
        with open(path, newline="") as f:
            for row in csv.DictReader(f):
                t, force = float(row["t_s"]), float(row["f_ext_n"])
                if last is None or abs(force - last) > 1e-9:
                    since, last = t, force
                if int(float(row["fault_code"])):
                    faults += 1
                    break
                if int(float(row["phase"])) == 3:
                    region.append(abs(float(row["f_ext_fused_n"])))
                elif region:
                    noload_n = max([noload_n] + region[len(region) // 2:])
                    region = []
                if t - since < 1.0:
                    continue
                n += 1
                inside += float(row["f_ext_lo_n"]) <= force <= float(row["f_ext_hi_n"])
                if abs(force) > 0.1:
                    loaded.setdefault(force, []).append(float(row["f_ext_fused_n"]))
                    theta = float(row["theta_true_rad"])
                    lo_rad, hi_rad = min(lo_rad, theta), max(hi_rad, theta)
        if region:
            noload_n = max([noload_n] + region[len(region) // 2:])
        covs.append(100.0 * inside / max(n, 1))
        if hi_rad > lo_rad:
            tip_pp = max(tip_pp, math.degrees(hi_rad - lo_rad))
        for force, v in loaded.items():
            acc = 100.0 * (1.0 - abs(sum(v) / len(v) - force) / abs(force))
            (big if abs(force) > 0.5 else small).append(acc)
    nan = float("nan")
    return {
        "least_cov": min(covs) if covs else nan,
        "holds<99.5": sum(c < 99.5 for c in covs),
        "worst>1N": min(big) if big else nan,
        "mean>1N": sum(big) / len(big) if big else nan,
        "worst0.3": min(small) if small else nan,
        "noload": noload_n,
        "faults": faults,
        "tip_pp": tip_pp,
    }


def line(s):
    """The one-line form the scripts print."""
    return (
        f"least_cov {s['least_cov']:.1f} holds<99.5 {s['holds<99.5']} "
        f"worst>1N {s['worst>1N']:.1f} mean>1N {s['mean>1N']:.1f} "
        f"worst0.3 {s['worst0.3']:.1f} noload {s['noload']:.3f} faults {s['faults']} "
        f"tip_pp {s['tip_pp']:.3f}"
    )


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: hold-stats.py HOLD.csv...")
    print(line(stats(sys.argv[1:])))
