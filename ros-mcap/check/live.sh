#!/usr/bin/env bash
# Live view check (CI step; issue 35): the three live views stream to an
# independent ws-protocol client (ros-mcap/check/live_check.py: PyPI
# `websockets`, written from the Foxglove WebSocket protocol's published
# spec) and what it receives is compared with the MCAP log of the same run:
# 1. `hil-sim run --live` with its --mcap: the client's messages equal the
#    log's (topics, schemas, times, bytes, decoded /odom values) and the
#    shipped layout (book/src/how-to/foxglove-layout.json) names only advertised
#    topics and fields;
# 2. `wmr serve --live` on the simulated robot (`hil-sim device --pty`),
#    `wmr record --arm --mcap` through the same server: every logged
#    message in the live stream, the same bytes but for a stamp shifted by
#    one constant (live_check.py --aligned);
# 3. `wmr-ros2 --live --mcap` on the simulated robot, in a private network
#    namespace (its DDS participant; wmr-ros2/check/netns.sh): the live
#    messages a contiguous run of the log's, the same times and bytes, the
#    log's stamps never repeating (live_check.py --tail).
# Loopback only, free ports.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$ROOT"
FAIL_PREFIX="live check: "
. scripts/check-lib.sh
. ros-mcap/check/lib.sh
. wmr-ros2/check/netns.sh
WEBSOCKETS_VERSION=17.4
HILSIM="$ROOT/target/release/hil-sim"
WMR="$ROOT/target/release/wmr"
BRIDGE="${LIVE_CHECK_BRIDGE:-$ROOT/target/release/wmr-ros2}" # another binary: to check the check
PIDS=()
trap 'for p in "${PIDS[@]}"; do stop_pid "$p"; done' EXIT

# live_url LOG PID: the first `live view: ws://...` address in LOG (a
# ceiling for a hang, not a timing check).
live_url() {
    local log=$1 pid=$2 url=""
    for _ in $(seq 600); do
        url=$(sed -n 's/.*live view: \(ws:[^ ]*\).*/\1/p' "$log" | head -1)
        [ -n "$url" ] && break
        kill -0 "$pid" 2>/dev/null || fail "the server exited: $(cat "$log")"
        sleep 0.1
    done
    [ -n "$url" ] || fail "no live view address in 60 s: $(cat "$log")"
    echo "$url"
}

# --- part 3, inside the private network namespace ---
if [ -n "${WMR_ROS2_IN_NETNS:-}" ]; then
    check_netns
    OUT="$LIVE_OUT"
    start_device "$OUT" --scenario wmr-ros2/check/scenario.toml --robot robots/tb6612-2kg.toml --for-s 60
    PIDS+=("$DEV_PID")
    "$BRIDGE" --port "$DEV_PTY" --live --live-port 0 --mcap "$OUT/bridge.mcap" --for-s 4 2>"$OUT/bridge.err" &
    BRIDGE_PID=$!
    PIDS+=("$BRIDGE_PID")
    URL=$(live_url "$OUT/bridge.err" "$BRIDGE_PID")
    echo "live view at $URL"
    # Until the bridge closes the view, after its log is finished.
    "$PY" ros-mcap/check/live_check.py --tail --min 100 "$URL" "$OUT/bridge.mcap" book/src/how-to/foxglove-layout.json ||
        fail "wmr-ros2 --live (the bridge's log: $OUT/bridge.err)"
    wait "$BRIDGE_PID" || fail "wmr-ros2: $(cat "$OUT/bridge.err")"
    exit 0
fi

OUT="$(mktemp -d)"
check_venv "${MCAP_CHECK_VENV:-$ROOT/target/ros-check-venv}"
if [ "$("$PY" -c 'import importlib.metadata as m; print(m.version("websockets"))' 2>/dev/null)" != "$WEBSOCKETS_VERSION" ]; then
    "$PY" -m pip install --quiet "websockets==$WEBSOCKETS_VERSION" || fail "pip install websockets==$WEBSOCKETS_VERSION"
fi
echo "websockets $WEBSOCKETS_VERSION"
build_host_tools
# No-op after the ROS 2 bridge step (the same command) built it.
(cd wmr-ros2 && CARGO_TARGET_DIR="$ROOT/target" cargo build --release --locked --quiet)
netns_tools

echo "== 1. hil-sim run --live (real time, 4 s) with --mcap, one client"
"$HILSIM" run --duration 4 --live --live-port 0 --live-wait --mcap "$OUT/live.mcap" \
    >"$OUT/run.txt" 2>"$OUT/run.err" &
SIM_PID=$!
PIDS+=("$SIM_PID")
URL=$(live_url "$OUT/run.err" "$SIM_PID")
echo "live view at $URL"
# The client reads until the server closes, which hil-sim does once the
# MCAP log of the run is written.
"$PY" ros-mcap/check/live_check.py "$URL" "$OUT/live.mcap" book/src/how-to/foxglove-layout.json
wait "$SIM_PID" || fail "hil-sim run --live: $(cat "$OUT/run.err")"

echo "== 2. wmr serve --live on hil-sim device, wmr upload, wmr record --arm --mcap through it (2 s)"
start_device "$OUT" --scenario wmr-ros2/check/scenario.toml --for-s 60
PIDS+=("$DEV_PID")
# The record's rate: both get every frame the robot sends.
"$WMR" serve --port "$DEV_PTY" --socket "$OUT/serve.sock" --live --live-port 0 --live-rate-hz 100 \
    >"$OUT/serve.out" 2>"$OUT/serve.err" &
SERVE_PID=$!
PIDS+=("$SERVE_PID")
URL=$(live_url "$OUT/serve.err" "$SERVE_PID")
echo "live view at $URL"
"$PY" ros-mcap/check/live_check.py --aligned --ready "$OUT/subscribed" "$URL" "$OUT/record.mcap" book/src/how-to/foxglove-layout.json &
CLIENT_PID=$!
PIDS+=("$CLIENT_PID")
for _ in $(seq 600); do
    [ -e "$OUT/subscribed" ] && break
    kill -0 "$CLIENT_PID" 2>/dev/null || fail "the client exited before subscribing"
    sleep 0.1
done
[ -e "$OUT/subscribed" ] || fail "the client did not subscribe in 60 s"
"$WMR" upload --serve "$OUT/serve.sock" trajectories/square.toml >"$OUT/upload.out" 2>&1 ||
    fail "wmr upload: $(cat "$OUT/upload.out")"
"$WMR" record --serve "$OUT/serve.sock" --seconds 2 --arm --quiet --mcap "$OUT/record.mcap" --out "$OUT/record.csv" \
    >"$OUT/record.json" 2>"$OUT/record.err" || fail "wmr record: $(cat "$OUT/record.err")"
"$WMR" disarm --serve "$OUT/serve.sock" >"$OUT/disarm.out" 2>&1 || fail "wmr disarm: $(cat "$OUT/disarm.out")"
# The server's end closes the view: the client then compares.
kill "$SERVE_PID"
wait "$CLIENT_PID" || fail "wmr serve --live (its log: $OUT/serve.err)"
wait "$SERVE_PID" || fail "wmr serve: $(cat "$OUT/serve.err")"
stop_pid "$DEV_PID"

echo "== 3. wmr-ros2 --live --mcap on hil-sim device (4 s), in a private network namespace"
export LIVE_OUT="$OUT" PY
in_netns bash "'$0'"
echo "live check: all passed ($OUT)"
