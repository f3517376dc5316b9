#!/usr/bin/env bash
# Is the report unchanged by a refactor? Builds BASE (a git revision,
# default HEAD, i.e. the last commit) in a separate worktree, runs
# `host-sim report` with it and with the working tree, and compares every
# file of the two report directories: report.json with its run times left
# out, report.md, the configurations, the plots (SVG and PNG) byte for byte.
#
#   bash scripts/report-unchanged.sh            # working tree against HEAD
#   bash scripts/report-unchanged.sh 94e3fc3    # against a revision
#   bash scripts/report-unchanged.sh --dir D    # against a report already
#                                               # written to D (no base build)
#
# Exit 0: identical; 1: a difference (listed); 2: a build or run failed.
# The base build goes to target/report-base (its own target directory, the
# first run compiles everything once: about 3 minutes on two cores).
set -euo pipefail
cd "$(dirname "$0")/.."
base_dir=""
if [ "${1:-}" = "--dir" ]; then
  base_dir="${2:?--dir needs a report directory}"
  set -- HEAD
fi
base_rev="${1:-HEAD}"
work="$(mktemp -d)"
# The base's worktree sits at a fixed path so that its build is reused.
tree="$PWD/target/report-base/src"
trap 'git worktree remove --force "$tree" >/dev/null 2>&1 || true; rm -rf "$work"' EXIT

if [ -z "$base_dir" ]; then
  git worktree remove --force "$tree" >/dev/null 2>&1 || rm -rf "$tree"
  git worktree prune
  git worktree add --detach --quiet "$tree" "$base_rev"
  echo "building the base ($(git rev-parse --short "$base_rev")) ..."
  CARGO_TARGET_DIR="$PWD/target/report-base" \
    cargo build --release --quiet -p host-sim --manifest-path "$tree/Cargo.toml" || exit 2
  target/report-base/release/host-sim report --quiet --out "$work/base" >/dev/null || exit 2
  base_dir="$work/base"
fi
echo "building the working tree ..."
cargo build --release --quiet -p host-sim || exit 2
echo "running the report ..."
target/release/host-sim report --quiet --out "$work/new" >/dev/null || exit 2

python3 - "$base_dir" "$work/new" <<'PY'
import json, os, re, sys

base, new = sys.argv[1], sys.argv[2]

def files(root):
    out = set()
    for d, _, fs in os.walk(root):
        for f in fs:
            out.add(os.path.relpath(os.path.join(d, f), root))
    return out

def without_runtime(x):
    if isinstance(x, dict):
        return {k: without_runtime(v) for k, v in x.items() if k != "runtime_s"}
    if isinstance(x, list):
        return [without_runtime(v) for v in x]
    return x

def md_text(path):
    # The report's first paragraph states the wall time of the run.
    text = open(path, encoding="utf-8").read()
    return re.sub(r" in [0-9.]+ s\. Everything below", " in T s. Everything below", text, count=1)

a, b = files(base), files(new)
diff = []
for f in sorted(a ^ b):
    diff.append(f"only in {'base' if f in a else 'new'}: {f}")
for f in sorted(a & b):
    pa, pb = os.path.join(base, f), os.path.join(new, f)
    if f.endswith(".json"):
        ja = without_runtime(json.load(open(pa)))
        jb = without_runtime(json.load(open(pb)))
        same = ja == jb
    elif f.endswith(".md"):
        same = md_text(pa) == md_text(pb)
    else:
        same = open(pa, "rb").read() == open(pb, "rb").read()
    if not same:
        diff.append(f"differs: {f}")
print(f"compared {len(a & b)} files")
if diff:
    print("\n".join(diff))
    sys.exit(1)
print("report unchanged")
PY
