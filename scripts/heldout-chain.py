#!/usr/bin/env python3
"""The passive and the probed force estimate through the user's calibration
chain, on plants drawn by scripts/spring-heldout.py's generator (none of
them a report draw; docs/force.md, "Held out on the same 40 plants" and
"Probing on the 40 held-out plants").

Per seed, at its control rate (seed mod 6: 2000, 1000, 2000, 1000, 500,
5000 Hz), every calibration run recorded at a row every tick (or every
`--every` N ticks, as a board streams by default with N = 10), as
README's "Calibrate your own machine" orders them:

    host-sim simulate --scenario bm-noload|jae-ident --plant pN.toml [--config R.toml]
    host-sim identify --procedure bm --log bm.csv [--config R.toml] --config-out cb.toml
    host-sim identify --procedure jae --log j.csv --config cb.toml --config-out cj.toml
    host-sim simulate --scenario tension-ident --plant pN.toml --config cj.toml
    host-sim identify --procedure tension --log t.csv --config cj.toml --config-out c.toml

then the seed's 18 loading holds (0, 30, -40 deg; 30, 100, 250 g; both
ways) on c.toml, passive, and again with `[probe] enabled = true` (c.toml
otherwise unchanged). Prints one line per seed and mode with
scripts/hold-stats.py's figures, then a summary per mode. The holds' CSVs
are deleted once counted.

    python3 scripts/heldout-chain.py --seeds 1-40 --out /tmp/chain

With `--family presliding` the plants are spring-heldout.py's harsher
family (docs/force.md, "Presliding guides and the spring fit"):

    python3 scripts/heldout-chain.py --family presliding --seeds 1-12 --out /tmp/pre

About 20 seconds per seed (14 minutes for 40) after `cargo build --release -p
host-sim`.
"""

import argparse
import importlib.util
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def load(name):
    """A sibling script as a module (their file names have hyphens)."""
    spec = importlib.util.spec_from_file_location(name.replace("-", "_"), os.path.join(HERE, name))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


plants = load("spring-heldout.py")
holds = load("hold-stats.py")
HOST_SIM = plants.HOST_SIM


def run(cmd, log=None):
    """spring-heldout.py's `run` (exits on a failure), its output kept in
    `log` when given."""
    text = plants.run(cmd)
    if log:
        with open(log, "w") as f:
            f.write(text)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1-40", help="first-last")
    ap.add_argument("--out", required=True, help="working directory")
    ap.add_argument("--every", type=int, default=1,
                    help="the calibration runs' row spacing, ticks (the holds keep every tick)")
    ap.add_argument("--family", choices=plants.FAMILIES, default="heldout",
                    help="spring-heldout.py's generator: `presliding` draws +/-50 %%, a static "
                         "friction up to twice the kinetic and presliding contacts on even seeds")
    a = ap.parse_args()
    every = ["--record-every", str(a.every)] if a.every > 1 else []
    first, last = (int(x) for x in a.seeds.split("-"))
    os.makedirs(a.out, exist_ok=True)
    defaults = plants.default_plant()
    results = {"passive": [], "probing": []}
    for seed in range(first, last + 1):
        d = os.path.join(a.out, f"p{seed}")
        os.makedirs(d, exist_ok=True)
        plant, _ = plants.drawn_plant(seed, defaults, a.family)
        rate = plants.seed_rate(seed, a.family)
        plant_path = os.path.join(d, "plant.toml")
        with open(plant_path, "w") as f:
            f.write(plant)
        rate_config = plants.rate_config(rate, d)
        p = lambda name: os.path.join(d, name)  # noqa: E731
        for scenario, log in [("bm-noload", "bm.csv"), ("jae-ident", "j.csv")]:
            run([HOST_SIM, "simulate", "--scenario", scenario, "--plant", plant_path,
                 *rate_config, *every, "--out", p(log)])
        run([HOST_SIM, "identify", "--procedure", "bm", "--log", p("bm.csv"), *rate_config,
             "--config-out", p("cb.toml")], p("idb.txt"))
        run([HOST_SIM, "identify", "--procedure", "jae", "--log", p("j.csv"), "--config",
             p("cb.toml"), "--config-out", p("cj.toml")], p("idj.txt"))
        run([HOST_SIM, "simulate", "--scenario", "tension-ident", "--plant", plant_path,
             "--config", p("cj.toml"), *every, "--out", p("t.csv")])
        run([HOST_SIM, "identify", "--procedure", "tension", "--log", p("t.csv"), "--config",
             p("cj.toml"), "--config-out", p("c.toml")], p("idt.txt"))
        for log in ["bm.csv", "j.csv", "t.csv"]:
            os.remove(p(log))
        with open(p("c.toml")) as f:
            text = f.read()
        if "[probe]\nenabled = false\n" not in text:
            sys.exit(f"{p('c.toml')}: no `[probe] enabled = false` to switch on")
        with open(p("cp.toml"), "w") as f:
            f.write(text.replace("[probe]\nenabled = false\n", "[probe]\nenabled = true\n"))
        for mode, config in [("passive", "c.toml"), ("probing", "cp.toml")]:
            paths = []
            for angle in [0, 30, -40]:
                for mass in [30, 100, 250]:
                    for direction in ["pos", "neg"]:
                        hold = p(f"{mode}_{angle}_{mass}_{direction}.csv")
                        run([HOST_SIM, "simulate", "--scenario", "loading", "--plant",
                             plant_path, "--config", p(config), "--angle-deg", str(angle),
                             "--mass-g", str(mass), "--direction", direction, "--out", hold])
                        paths.append(hold)
            s = holds.stats(paths)
            for path in paths:
                os.remove(path)
            results[mode].append(s)
            print(f"seed {seed} {rate:g} Hz {mode} {holds.line(s)}", flush=True)
    for mode, rows in results.items():
        if not rows:
            continue
        worst = sorted(r["worst>1N"] for r in rows)
        print(f"{mode}: {len(rows)} plants; least hold coverage {min(r['least_cov'] for r in rows):.1f} %; "
              f"worst above 1 N {worst[0]:.1f} to {worst[-1]:.1f} % (median {worst[len(worst) // 2]:.1f}); "
              f">= 90 % on {sum(w >= 90 for w in worst)}, >= 94 % and >= 82 % at 0.3 N on "
              f"{sum(r['worst>1N'] >= 94 and r['worst0.3'] >= 82 for r in rows)}; "
              f"static no-load {min(r['noload'] for r in rows):.3f} to "
              f"{max(r['noload'] for r in rows):.3f} N (<= 0.1 N on "
              f"{sum(r['noload'] <= 0.1 for r in rows)}); "
              f"faults {sum(r['faults'] for r in rows)}; tip motion <= 0.5 deg on "
              f"{sum(r['tip_pp'] <= 0.5 for r in rows)}")


if __name__ == "__main__":
    main()
