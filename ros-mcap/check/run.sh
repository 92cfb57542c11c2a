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
MCAP_VERSION=1.6.0
ROSBAGS_VERSION=0.11.9
OUT="$(mktemp -d)"
DEV_PID=""
cleanup() { [ -n "$DEV_PID" ] && kill "$DEV_PID" 2>/dev/null || true; }
trap cleanup EXIT
fail() { echo "mcap check: FAIL: $*" >&2; exit 1; }

VENV="${MCAP_CHECK_VENV:-$ROOT/target/mcap-check-venv}"
if ! "$VENV/bin/python" -c "import mcap, rosbags" 2>/dev/null ||
    [ "$("$VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("mcap"), m.version("rosbags"))')" != "$MCAP_VERSION $ROSBAGS_VERSION" ]; then
    python3 -m venv "$VENV" || fail "python3 -m venv (apt-get install python3-venv)"
    "$VENV/bin/pip" install --quiet "mcap==$MCAP_VERSION" "rosbags==$ROSBAGS_VERSION" ||
        fail "pip install mcap==$MCAP_VERSION rosbags==$ROSBAGS_VERSION"
fi
PY="$VENV/bin/python"
echo "python: $("$PY" --version), mcap $("$PY" -c 'import importlib.metadata as m; print(m.version("mcap"))'), rosbags $("$PY" -c 'import importlib.metadata as m; print(m.version("rosbags"))')"

cargo build --release -p hil-sim -p wmr
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
"$HILSIM" device --pty --for-s 60 >"$OUT/dev.out" 2>"$OUT/dev.err" </dev/null &
DEV_PID=$!
t_end=$((SECONDS + 10))
until [ -s "$OUT/dev.out" ]; do
    kill -0 "$DEV_PID" 2>/dev/null || fail "hil-sim device exited: $(cat "$OUT/dev.err")"
    [ "$SECONDS" -lt "$t_end" ] || fail "hil-sim device named no pty within 10 s"
    sleep 0.1
done
PTY="$(head -1 "$OUT/dev.out")"
"$WMR" --port "$PTY" upload trajectories/square.toml
"$WMR" --port "$PTY" record --seconds 5 --arm --quiet --out "$OUT/rec.csv" --mcap "$OUT/rec.mcap" >"$OUT/rec.json" ||
    fail "wmr record --mcap: $(cat "$OUT/rec.json")"
"$WMR" --port "$PTY" disarm >/dev/null
"$PY" ros-mcap/check/mcap_check.py "$OUT/rec.mcap" "$OUT/rec.csv"
"$WMR" metrics "$OUT/rec.csv" >"$OUT/rec_csv.json"
"$WMR" metrics "$OUT/rec.mcap" >"$OUT/rec_mcap.json"
cmp "$OUT/rec_csv.json" "$OUT/rec_mcap.json" || fail "wmr metrics differs between rec.csv and rec.mcap"
echo "wmr metrics: CSV and MCAP give the same JSON: $(cat "$OUT/rec_csv.json")"
echo "mcap check: all passed ($OUT)"
