#!/usr/bin/env bash
# Benchmark of a default tuning job (issue 19, BENCHMARKS.md "Tuning"):
# runs `hil-sim tune --robot FILE` with its defaults (or the extra flags
# given after the file) and prints the wall-clock time, the simulations
# run, their rate, the thread count and the load average before and after
# (the machine may be shared), and the job's CPU time (user + system: on
# 2 idle cores the wall time is about half of it). HIL_SIM=PATH runs that
# binary instead of building this checkout's. Usage:
#   bash hil-sim/bench-tune.sh robots/paper.toml [extra tune flags]
set -euo pipefail
robot=${1:?usage: bench-tune.sh ROBOT.toml [tune flags]}
shift
cd "$(dirname "$0")/.."
bin=${HIL_SIM:-}
if [ -z "$bin" ]; then
    cargo build --release -p hil-sim --quiet
    bin=./target/release/hil-sim
fi
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
load0=$(cut -d' ' -f1-3 /proc/loadavg)
t0=$(date +%s.%N)
status=0
/usr/bin/time -f "%U %S" -o "$out/cpu.txt" "$bin" tune --robot "$robot" --quiet \
    --write "$out/tuned.toml" --out "$out/raw.json" "$@" > "$out/table.txt" || status=$?
t1=$(date +%s.%N)
load1=$(cut -d' ' -f1-3 /proc/loadavg)
python3 - "$out/raw.json" "$t0" "$t1" "$load0" "$load1" "$robot" "$out/cpu.txt" "$status" <<'PY'
import json, sys
raw, t0, t1, l0, l1, robot, cpu, status = sys.argv[1:]
d = json.load(open(raw))
wall = float(t1) - float(t0)
user, system = (float(x) for x in open(cpu).read().split()[-2:])
n = d["simulations"]
print(f"robot {robot}: {n} simulations in {wall:.1f} s wall "
      f"({n / wall:.1f} simulations/s, {d['threads']} threads, "
      f"{d['job']['evaluations']} evaluations x {d['job']['set']['training']} training "
      f"+ {d['job']['set']['validation']} validation scenarios per controller)")
print(f"CPU {user + system:.1f} s (user {user:.1f}, system {system:.1f}): "
      f"on 2 idle cores about {(user + system) / 2:.0f} s wall; exit status {status}")
print(f"load average (1, 5, 15 min) before: {l0}; after: {l1}")
PY
cat "$out/table.txt"
