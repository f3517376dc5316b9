#!/usr/bin/env python3
"""How much, and at what frequency, a log's current reference chatters (a
study of `host-sim simulate` logs; README, "Where the cycles sit").

For each CSV log it prints:

* the mean of |i_ref_a[k] - i_ref_a[k-1]| over the rows after the first
  5 % (the README's "A per tick");
* the median, over 0.2 s windows between --from and --to (default 1 to
  15 s: the sines of `tension-ident`), of the RMS of the current minus its
  0.1 s moving mean (a high-pass near 10 Hz);
* the strongest line of that high-passed current between 10 Hz and the
  Nyquist rate over --line-from to --line-to (default 5 to 7 s), on a
  2 Hz grid;
* the first fault code and its time, if any.

    host-sim simulate --scenario tension-ident --config V/config.toml \\
        --plant V/plant.toml --out t.csv
    python3 scripts/current-chatter.py t.csv

Standard library only (the log reader is `logcsv.py`, beside this
script).
"""

import argparse
import cmath
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import logcsv  # noqa: E402


def load(path):
    col = logcsv.read_columns(path, ["t_s", "i_ref_a"], optional=["fault_code"], min_rows=3)
    t, i = col["t_s"], col["i_ref_a"]
    # The first row with a fault: an empty cell (NaN) or 0 is none.
    codes = col.get("fault_code", [])
    fault = next(((f"{c:g}", t[k]) for k, c in enumerate(codes) if c == c and c != 0), None)
    return t, i, fault


def high_passed(t, i, t0, t1, rate_hz):
    """The current minus its 0.1 s moving mean, for t0 < t < t1."""
    half = max(1, int(0.05 * rate_hz))
    sums = [0.0]
    for v in i:
        sums.append(sums[-1] + v)
    out = []
    for k in range(half, len(i) - half):
        if t0 < t[k] < t1:
            out.append(i[k] - (sums[k + half] - sums[k - half]) / (2 * half))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs", nargs="+")
    ap.add_argument("--from", dest="t0", type=float, default=1.0)
    ap.add_argument("--to", dest="t1", type=float, default=15.0)
    ap.add_argument("--line-from", type=float, default=5.0)
    ap.add_argument("--line-to", type=float, default=7.0)
    a = ap.parse_args()
    for path in a.logs:
        t, i, fault = load(path)
        rate_hz = round(1.0 / (t[1] - t[0]))
        start = len(i) // 20
        per_tick = sum(abs(i[k] - i[k - 1]) for k in range(max(1, start), len(i))) / (
            len(i) - max(1, start)
        )
        hp = high_passed(t, i, a.t0, a.t1, rate_hz)
        n = max(1, int(0.2 * rate_hz))
        rms = sorted(
            math.sqrt(sum(v * v for v in hp[j : j + n]) / n) for j in range(0, len(hp) - n + 1, n)
        )
        median = rms[len(rms) // 2] if rms else float("nan")
        seg = high_passed(t, i, a.line_from, a.line_to, rate_hz)
        best = (0.0, float("nan"))
        for f_hz in range(10, rate_hz // 2, 2):
            w = -2j * math.pi * f_hz / rate_hz
            amp = abs(sum(v * cmath.exp(w * k) for k, v in enumerate(seg)))
            best = max(best, (amp, f_hz))
        where = f"fault {fault[0]} at {fault[1]:.2f} s" if fault else "no fault"
        print(
            f"{path}: {rate_hz} Hz, {per_tick:.3f} A per tick, median 0.2 s RMS "
            f"{median:.3f} A, strongest line {best[1]} Hz, {where}"
        )


if __name__ == "__main__":
    main()
