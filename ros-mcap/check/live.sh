#!/usr/bin/env bash
# Live view check (CI step; issue 35): `hil-sim run --live` streams a
# simulation to an independent ws-protocol client (ros-mcap/check/
# live_check.py: PyPI `websockets`, written from the Foxglove WebSocket
# protocol's published spec) while the same run writes its MCAP log; the
# client's messages must equal the log's (topics, schemas, times, bytes,
# decoded /odom values) and the shipped layout (book/src/how-to/foxglove-layout.json)
# must name only advertised topics and fields. Loopback only, a free port.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$ROOT"
OUT="$(mktemp -d)"
SIM_PID=""
FAIL_PREFIX="live check: "
. scripts/check-lib.sh
. ros-mcap/check/lib.sh
trap 'stop_pid "$SIM_PID"' EXIT
WEBSOCKETS_VERSION=17.4

check_venv "${MCAP_CHECK_VENV:-$ROOT/target/ros-check-venv}"
if [ "$("$PY" -c 'import importlib.metadata as m; print(m.version("websockets"))' 2>/dev/null)" != "$WEBSOCKETS_VERSION" ]; then
    "$PY" -m pip install --quiet "websockets==$WEBSOCKETS_VERSION" || fail "pip install websockets==$WEBSOCKETS_VERSION"
fi
echo "websockets $WEBSOCKETS_VERSION"
build_host_tools
HILSIM="$ROOT/target/release/hil-sim"

echo "== hil-sim run --live (real time, 4 s) with --mcap, one client"
"$HILSIM" run --duration 4 --live --live-port 0 --live-wait --mcap "$OUT/live.mcap" \
    >"$OUT/run.txt" 2>"$OUT/run.err" &
SIM_PID=$!
# The address it printed first (a ceiling for a hang, not a timing check).
for _ in $(seq 600); do
    URL=$(sed -n 's/^live view: \(ws:[^ ]*\)$/\1/p' "$OUT/run.err" | head -1)
    [ -n "$URL" ] && break
    kill -0 "$SIM_PID" 2>/dev/null || fail "hil-sim run --live exited: $(cat "$OUT/run.err")"
    sleep 0.1
done
[ -n "$URL" ] || fail "no live view address in 60 s: $(cat "$OUT/run.err")"
echo "live view at $URL"
# The client reads until the server closes, which hil-sim does once the
# MCAP log of the run is written.
"$PY" ros-mcap/check/live_check.py "$URL" "$OUT/live.mcap" book/src/how-to/foxglove-layout.json
wait "$SIM_PID" || fail "hil-sim run --live: $(cat "$OUT/run.err")"
SIM_PID=""
echo "live check: all passed ($OUT)"
