#!/usr/bin/env python3
"""Where the spring fit through the motor is biased: per-sweep slopes of a
simulated calibration log's tensions against x2 (docs/force.md, "Where the
bias sits").

    python3 scripts/spring-sweeps.py LOG.csv PLANT_SPRING_N_M

LOG.csv is a `host-sim simulate --scenario jae-ident` log (it carries the
simulator's truth columns). A sweep is a run of rows in which both sliders
move the same way faster than 0.2 mm/s for more than 0.3 s; its row is the
mean over its last third less the mean over its first third (after
50 ms). For each tension (`tension1_hat_n` the DOB's, `f1_true_n` cable 0
at the rope wheel, `fw1_true_n` cable 1) it prints the median per-sweep
slope and least-squares fits of the rows on x2 (K only), on x2, x2', x2''
(identify's regressors), and on those plus a column for friction that
differs between the accelerating and the decelerating part of a sweep.
Needs numpy.
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import logcsv  # noqa: E402

COLS = ["t_s", "x1_vel_m_s", "x2_m", "x2_vel_m_s", "x2_acc_m_s2",
        "tension1_hat_n", "f1_true_n", "fw1_true_n"]
SOURCES = [("DOB", "tension1_hat_n"), ("cable 0 (true)", "f1_true_n"),
           ("cable 1 (true)", "fw1_true_n")]


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    path, spring = sys.argv[1], float(sys.argv[2])
    d = {c: np.array(v) for c, v in logcsv.read_columns(path, COLS, min_rows=2).items()}
    dt = d["t_s"][1] - d["t_s"][0]
    v1, v2 = d["x1_vel_m_s"], d["x2_vel_m_s"]
    w = max(1, int(0.02 / dt))
    acc = np.gradient(np.convolve(v2, np.ones(w) / w, mode="same"), dt)
    moving = (np.abs(v1) > 2e-4) & (np.abs(v2) > 2e-4) & (np.sign(v1) == np.sign(v2))
    x, y = [], {c: [] for _, c in SOURCES}
    k, n = 0, len(v2)
    while k < n:
        if not moving[k]:
            k += 1
            continue
        s, j = np.sign(v2[k]), k
        while j < n and moving[j] and np.sign(v2[j]) == s:
            j += 1
        length = j - k
        a, b = slice(k + int(0.05 / dt), k + length // 3), slice(j - length // 3, j)
        if length * dt > 0.3 and a.stop > a.start:
            diff = lambda c: d[c][b].mean() - d[c][a].mean()
            # +1 accelerating, -1 decelerating. A friction of the motion's
            # sign that differs between the two, s (f0 + f1 / 2 (1 +
            # accelerating)), varies by s f1 / 2 accelerating: hence `s`
            # once more on the column (which so equals sign(acc), s² = 1).
            accelerating = np.sign(acc) * s
            x.append([diff("x2_m"), diff("x2_vel_m_s"), diff("x2_acc_m_s2"),
                      s * (accelerating[b].mean() - accelerating[a].mean())])
            for _, c in SOURCES:
                y[c].append(diff(c))
        k = j
    x = np.array(x)
    if len(x) < 6:
        sys.exit(f"{path}: {len(x)} sweeps, too few to fit")
    print(f"{path}: {len(x)} sweeps, plant spring {spring:.0f} N/m")
    fit = lambda cols, t: np.linalg.lstsq(x[:, cols], t, rcond=None)[0][0]
    for name, c in SOURCES:
        t = np.array(y[c])
        print(f"  {name:15s} median slope {np.median(t / x[:, 0]):6.0f}  K only {fit([0], t):6.0f}"
              f"  x2,x2',x2'' {fit([0, 1, 2], t):6.0f}  with the acceleration column"
              f" {fit([0, 1, 2, 3], t):6.0f} N/m")


if __name__ == "__main__":
    main()
