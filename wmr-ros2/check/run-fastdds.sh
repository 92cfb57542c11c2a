#!/usr/bin/env bash
# ROS 2 interop check of the bridge against Fast DDS (CI step; issue 35):
# Debian's Fast DDS 2.9 (the DDS of rmw_fastrtps, ROS 2's default RMW), a
# client generated from the ROS 2 IDL types (check/fastdds/), against
# `wmr-ros2` bridging `hil-sim device --pty`, with its default service
# mapping (auto). The client is also the Nav2 stand-in over Fast DDS (pure
# pursuit at 20 Hz, a localiser at 10 Hz 60 ms late). Every DDS participant
# runs inside a private network namespace, as in run.sh. First, the bridge
# must refuse to start on a robot that cannot tell its d.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$ROOT"
FAIL_PREFIX="ros2 fastdds interop: "
. scripts/check-lib.sh
. wmr-ros2/check/netns.sh

CLIENT="$ROOT/target/fastdds-check/wmr_fastdds_client"
if [ -z "${WMR_ROS2_IN_NETNS:-}" ]; then
    netns_tools
    command -v fastddsgen >/dev/null || fail "fastddsgen not found (apt-get install fastddsgen libfastrtps-dev libfastcdr-dev g++)"
    [ -x target/release/hil-sim ] || fail "target/release/hil-sim not built (the workspace's test build)"
    (cd wmr-ros2 && cargo build --release --locked)
    wmr-ros2/check/fastdds/build.sh "$CLIENT"
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
# d from the robot on the link: a robot whose d is not the paper's 0.05 m
ROBOT_FILE=robots/tb6612-2kg.toml
EXPECT_COM_OFFSET_M="$(awk -F'=' '/^com_offset_m/ {gsub(/[ \t]|#.*/, "", $2); print $2; exit}' "$ROBOT_FILE")"
[ -n "$EXPECT_COM_OFFSET_M" ] || fail "no com_offset_m in $ROBOT_FILE"
export EXPECT_COM_OFFSET_M
# A robot that cannot tell its d (a robot file pushed without a reboot: the
# stored record is not the one in force): the bridge refuses to start,
# naming the reason and --com-offset-m, rather than take the paper's 0.05 m.
start_device "$OUT" --scenario wmr-ros2/check/scenario.toml --robot "$ROBOT_FILE" --for-s 30
"$ROOT/target/release/wmr" robot push --no-reboot --port "$DEV_PTY" robots/paper.toml >"$OUT/push.out" 2>&1 ||
    fail "wmr robot push --no-reboot: $(cat "$OUT/push.out")"
if "$ROOT/target/release/wmr-ros2" --port "$DEV_PTY" --for-s 5 2>"$OUT/unknown-d.err"; then
    fail "the bridge started on a robot that cannot tell its d: $(cat "$OUT/unknown-d.err")"
fi
grep -q -- "--com-offset-m" "$OUT/unknown-d.err" || fail "the bridge's refusal does not name --com-offset-m: $(cat "$OUT/unknown-d.err")"
echo "d unknown to the robot: the bridge refused to start: $(tail -1 "$OUT/unknown-d.err")"
stop_pid "$DEV_PID"
DEV_PID=""
start_device "$OUT" --scenario wmr-ros2/check/scenario.toml --robot "$ROBOT_FILE" --for-s 150
# Kilted's Nav2 defaults (TwistStamped cmd_vel); the services' mapping auto
"$ROOT/target/release/wmr-ros2" --port "$DEV_PTY" --ros-distro kilted --cmd-timeout-ms 500 --for-s 140 2>"$OUT/bridge.err" &
BRIDGE_PID=$!
sleep 0.5
kill -0 "$BRIDGE_PID" 2>/dev/null || fail "wmr-ros2 exited: $(cat "$OUT/bridge.err")"
status=0
timeout 130 "$CLIENT" || status=$?
echo "--- wmr-ros2's log:"
cat "$OUT/bridge.err"
grep -q "refused service" "$OUT/bridge.err" && fail "the bridge refused a Fast DDS service request (see its log)"
[ "$status" -eq 0 ] || fail "the Fast DDS client exited $status ($OUT)"
echo "ros2 fastdds interop: all passed ($OUT)"
