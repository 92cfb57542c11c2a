#!/usr/bin/env bash
# Independent reader check of the MCAP logs (CI step; issue 20): the PyPI
# `mcap` and `rosbags` packages (exact versions, in a venv) read and decode
# every message of
#   1. `hil-sim run --mcap` (a simulated run), and
#   2. `wmr record --mcap` against `hil-sim device --pty` (the robot side),
# and check the values against the CSV each run wrote beside it
# (ros-mcap/check/mcap_check.py). Fails loudly on any step.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$ROOT"
OUT="$(mktemp -d)"
DEV_PID=""
FAIL_PREFIX="mcap check: "
. scripts/check-lib.sh
. ros-mcap/check/lib.sh
trap 'stop_pid "$DEV_PID"' EXIT

check_venv "${MCAP_CHECK_VENV:-$ROOT/target/ros-check-venv}"
build_host_tools
HILSIM="$ROOT/target/release/hil-sim"
WMR="$ROOT/target/release/wmr"

echo "== simulated run: hil-sim run --mcap (case 2: faults, governor off)"
"$HILSIM" run --duration 8 --csv "$OUT/sim.csv" --mcap "$OUT/sim.mcap" >/dev/null
"$PY" ros-mcap/check/mcap_check.py "$OUT/sim.mcap" "$OUT/sim.csv"
"$WMR" metrics "$OUT/sim.csv" >"$OUT/sim_csv.json"
"$WMR" metrics "$OUT/sim.mcap" >"$OUT/sim_mcap.json"
cmp "$OUT/sim_csv.json" "$OUT/sim_mcap.json" || fail "wmr metrics differs between sim.csv and sim.mcap"
echo "wmr metrics: CSV and MCAP give the same JSON: $(cat "$OUT/sim_csv.json")"

echo "== robot side: wmr record --mcap against hil-sim device --pty"
start_device "$OUT" --for-s 60
"$WMR" --port "$DEV_PTY" upload trajectories/square.toml
"$WMR" --port "$DEV_PTY" record --seconds 5 --arm --quiet --out "$OUT/rec.csv" --mcap "$OUT/rec.mcap" >"$OUT/rec.json" ||
    fail "wmr record --mcap: $(cat "$OUT/rec.json")"
"$WMR" --port "$DEV_PTY" disarm >/dev/null
"$PY" ros-mcap/check/mcap_check.py "$OUT/rec.mcap" "$OUT/rec.csv"
"$WMR" metrics "$OUT/rec.csv" >"$OUT/rec_csv.json"
"$WMR" metrics "$OUT/rec.mcap" >"$OUT/rec_mcap.json"
cmp "$OUT/rec_csv.json" "$OUT/rec_mcap.json" || fail "wmr metrics differs between rec.csv and rec.mcap"
echo "wmr metrics: CSV and MCAP give the same JSON: $(cat "$OUT/rec_csv.json")"
echo "mcap check: all passed ($OUT)"
