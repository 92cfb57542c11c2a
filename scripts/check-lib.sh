# Shell helpers of the check scripts (firmware-emu/run.sh, stm32-emu/run.sh,
# ros-mcap/check/run.sh, wmr-ros2/check/run.sh), sourced by each after it
# sets ROOT (the repository's root).
#
# Variables read: FAIL_PREFIX (fail's prefix, e.g. "mcap check: "); LOG and
# LOG_NAME (a log whose last lines fail prints, and what it is).

# step TEXT: a section heading.
step() { printf '\n== %s\n' "$*"; }

# fail MSG: one FAIL line on stderr, the last 15 lines of $LOG when it has
# any, and exit 1.
fail() {
    echo "${FAIL_PREFIX:-}FAIL: $*" >&2
    if [ -n "${LOG:-}" ] && [ -s "$LOG" ]; then
        echo "---- last lines of ${LOG_NAME:-the log} ($LOG):" >&2
        tail -15 "$LOG" >&2
    fi
    exit 1
}

# stop_pid PID: stops a background process of this shell if it still runs
# (SIGTERM; SIGKILL after 5 s) and reaps it; nothing when PID is empty.
stop_pid() {
    local pid=$1
    if [ -z "$pid" ] || ! kill -0 "$pid" 2>/dev/null; then
        return 0
    fi
    kill "$pid" 2>/dev/null || true
    for _ in $(seq 50); do
        kill -0 "$pid" 2>/dev/null || break
        sleep 0.1
    done
    kill -9 "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
}

# start_device OUT ARGS...: `hil-sim device --pty ARGS` in the background,
# its output in OUT/dev.out and OUT/dev.err; sets DEV_PID and DEV_PTY (the
# pseudo-terminal it named) or fails within 10 s.
start_device() {
    local out=$1
    shift
    rm -f "$out/dev.out"
    "$ROOT/target/release/hil-sim" device --pty "$@" >"$out/dev.out" 2>"$out/dev.err" </dev/null &
    DEV_PID=$!
    local t_end=$((SECONDS + 10))
    until [ -s "$out/dev.out" ]; do
        kill -0 "$DEV_PID" 2>/dev/null || fail "hil-sim device exited: $(cat "$out/dev.err")"
        [ "$SECONDS" -lt "$t_end" ] || fail "hil-sim device named no pty within 10 s"
        sleep 0.1
    done
    DEV_PTY="$(head -1 "$out/dev.out")"
}
