#!/usr/bin/env bash
# ROS 2 interop check of the bridge (CI step; issue 20): a CycloneDDS
# participant (PyPI cyclonedds, exact version, in a venv) against
# `wmr-ros2` bridging `hil-sim device --pty` (wmr-ros2/check/interop.py).
# Every DDS participant runs inside a private network namespace (loopback
# only, multicast routed to it): discovery never leaves the machine.
# Fails loudly on any step.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$ROOT"
FAIL_PREFIX="ros2 interop: "
. scripts/check-lib.sh
. ros-mcap/check/lib.sh
. wmr-ros2/check/netns.sh

if [ -z "${WMR_ROS2_IN_NETNS:-}" ]; then
    netns_tools
    check_venv "${ROS2_CHECK_VENV:-$ROOT/target/ros-check-venv}"
    build_host_tools
    (cd wmr-ros2 && cargo build --release --locked)
    # Everything below runs in the namespace (this script again).
    export ROS2_PY="$PY"
    in_netns bash "'$0'"
    exit
fi

# --- inside the private network namespace ---
check_netns
OUT="$(mktemp -d)"
DEV_PID=""
BRIDGE_PID=""
cleanup() {
    stop_pid "$BRIDGE_PID"
    stop_pid "$DEV_PID"
}
trap cleanup EXIT
# A robot whose d (body.com_offset_m) is not the paper's 0.05 m: the bridge
# must take d from the robot on the link (issue 32), and interop.py checks
# every /odom against the telemetry's G moved back by that d.
ROBOT_FILE=robots/tb6612-2kg.toml
EXPECT_COM_OFFSET_M="$(awk -F'=' '/^com_offset_m/ {gsub(/[ \t]|#.*/, "", $2); print $2; exit}' "$ROBOT_FILE")"
[ -n "$EXPECT_COM_OFFSET_M" ] || fail "no com_offset_m in $ROBOT_FILE"
export EXPECT_COM_OFFSET_M
start_device "$OUT" --scenario wmr-ros2/check/scenario.toml --robot "$ROBOT_FILE" --for-s 120
"$ROOT/target/release/wmr-ros2" --port "$DEV_PTY" --cmd-vel-type stamped --cmd-timeout-ms 500 --mcap "$OUT/bridge.mcap" \
    --for-s 110 2>"$OUT/bridge.err" &
BRIDGE_PID=$!
sleep 0.5
kill -0 "$BRIDGE_PID" 2>/dev/null || fail "wmr-ros2 exited: $(cat "$OUT/bridge.err")"
status=0
BRIDGE_PID="$BRIDGE_PID" timeout 100 "$ROS2_PY" wmr-ros2/check/interop.py "$OUT/bridge.mcap" || status=$?
echo "--- wmr-ros2's log:"
cat "$OUT/bridge.err"
wait "$BRIDGE_PID" || { [ "$status" -ne 0 ] || fail "wmr-ros2 exited $? after SIGTERM"; }
[ "$status" -eq 0 ] || fail "interop.py exited $status ($OUT)"
BRIDGE_PID=""
echo "ros2 interop: all passed ($OUT)"
