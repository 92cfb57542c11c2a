#!/usr/bin/env bash
# The emulated board, end to end (issue 11). Builds the firmware's
# application for the emulated board (thumbv7em-none-eabihf, QEMU
# mps2-an386) and the host tool `wmr`, boots the board under QEMU with
# -icount (one guest instruction per virtual ns), and drives it over the
# emulated UART (a pseudo-terminal) as a user drives a robot:
#   wmr status; wmr upload trajectories/square.toml;
#   wmr record --seconds 10 --arm (CSV + metrics); wmr disarm; wmr status.
# Fails (non-zero, one FAIL line) unless
#   (a) the board answers, records RECORD_S s of telemetry at 100 Hz with at
#       most MAX_DROPPED_FRAMES frames missing, and ends in hold after the
#       disarm, with no safe stop, watchdog reset, panic or fault;
#   (b) the recorded tracking matches hil-sim's runtime path: the same
#       commands drive `hil-sim device --pty` with the same robot
#       (firmware-emu/reference.toml: the firmware's encoders, motors, PWM,
#       a gyro, no perturbations); the emulated board's RMS position error
#       must be within REL_TOL_RMS (15 %) of hil-sim's and its final error
#       within REL_TOL_FINAL (25 %): the same code and plant differ only by
#       the gyro's noise sequence and the host's timing (measured: 0.0346 m
#       RMS, 0.066 m final on both, README). And, absolutely, RMS <=
#       RMS_BOUND_M (0.05 m): the robot follows the square;
#   (c) the worst control tick stays under TICK_BUDGET instructions
#       (default 20000: 20 % of a 1 ms period at 100 MHz), with and without
#       link traffic, and no tick starts late (virtual time is the
#       instruction count, so only the firmware's own work could delay one);
#   (d) negative control (WATCHDOG_CHECK=1, default): the same firmware
#       built with `stall-test` hogs its executor 3 s after boot; the
#       watchdog must cut the motors (NMI) and reset the board.
# Prints the tick's instructions (mean, max, max with link traffic).
#
# Usage: firmware-emu/run.sh        (from anywhere; installs what it needs)
# Env:   OUT_DIR=<dir for the CSVs and the log>  RECORD_S=10  TICK_BUDGET=20000
#        RMS_BOUND_M=0.05  REL_TOL_RMS=0.15  REL_TOL_FINAL=0.25
#        MAX_DROPPED_FRAMES=10
#        WATCHDOG_CHECK=1  QEMU_BOOT_TIMEOUT=20  EVENT_TIMEOUT=120
#        QEMU_ICOUNT=<-icount options; default shift=0,align=off,sleep=off>
set -euo pipefail
cd "$(dirname "$0")"
ROOT="$(cd .. && pwd)"

RECORD_S="${RECORD_S:-10}"
TICK_BUDGET="${TICK_BUDGET:-20000}"
RMS_BOUND_M="${RMS_BOUND_M:-0.05}"
REL_TOL_RMS="${REL_TOL_RMS:-0.15}"
REL_TOL_FINAL="${REL_TOL_FINAL:-0.25}"
MAX_DROPPED_FRAMES="${MAX_DROPPED_FRAMES:-10}"
WATCHDOG_CHECK="${WATCHDOG_CHECK:-1}"
QEMU_BOOT_TIMEOUT="${QEMU_BOOT_TIMEOUT:-20}"
# Ceiling [wall s] of a wait for something the board does at a virtual time
# (QEMU runs at a fraction of real time, less on a loaded machine): the
# wait ends on the board's line, this only bounds a hang.
EVENT_TIMEOUT="${EVENT_TIMEOUT:-120}"
OUT_DIR="${OUT_DIR:-$(mktemp -d)}"
mkdir -p "$OUT_DIR"
TARGET=thumbv7em-none-eabihf
ELF="target/$TARGET/release/firmware-emu"
WMR="$ROOT/target/release/wmr"
LOG="$OUT_DIR/emu.log"
CSV="$OUT_DIR/emu_square.csv"
REF_CSV="$OUT_DIR/hilsim_square.csv"
T_START=$SECONDS

LOG_NAME="the board's log"
. "$ROOT/scripts/check-lib.sh"

QPID=""
DEV_PID=""
cleanup() {
    exec 3<&-
    stop_pid "$QPID"
    stop_pid "$DEV_PID"
    QPID=""
    DEV_PID=""
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# Virtual time is the instruction count alone: the guest never idles (its
# thread mode spins instead of WFI: firmware-emu/src/main.rs) and
# sleep=off, so the host's scheduling cannot move it. A late tick is the
# firmware's own, and check (c) requires none (README: "QEMU command line").
QEMU_ARGS=(-machine mps2-an386 -cpu cortex-m4 -nographic -monitor none
    -semihosting-config enable=on,target=native
    -icount "${QEMU_ICOUNT:-shift=0,align=off,sleep=off}")

step "tools"
if ! command -v qemu-system-arm >/dev/null 2>&1; then
    SUDO=""
    if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
    $SUDO apt-get update
    $SUDO apt-get install -y qemu-system-arm
fi
rustup target add "$TARGET" >/dev/null
echo "machine: $(uname -m), $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg); $(qemu-system-arm --version | head -1); $(rustc --version)"

step "build: the guest (release; and its stall-test variant), wmr and hil-sim"
# The variant first, copied aside: the two differ only in this crate, so the
# dependencies build once.
STALL_ELF="$OUT_DIR/firmware-emu-stall-test.elf"
if [ "$WATCHDOG_CHECK" = "1" ]; then
    nice cargo build --release --locked --features stall-test
    cp "$ELF" "$STALL_ELF"
fi
nice cargo build --release --locked
# wmr and hil-sim as the README's test command builds them (its features;
# `cargo build -p wmr -p hil-sim` would compile the stack again: D124).
(cd "$ROOT" && nice cargo test --release --locked --workspace --no-run --quiet)

# Starts QEMU on ELF $1 with extra arguments; sets QPID.
start_qemu() {
    local elf="$1"
    shift
    : >"$LOG"
    qemu-system-arm "${QEMU_ARGS[@]}" "$@" -kernel "$elf" >"$LOG" 2>&1 </dev/null &
    QPID=$!
}

# Waits until the log has a line matching $1 (up to $2 s); fails otherwise.
wait_for_log() {
    local pattern="$1" t_end=$((SECONDS + $2))
    until grep -q -- "$pattern" "$LOG"; do
        kill -0 "$QPID" 2>/dev/null || fail "QEMU exited before printing \"$pattern\""
        [ "$SECONDS" -lt "$t_end" ] || fail "no \"$pattern\" from the board within $2 s"
        sleep 0.1
    done
}

# Waits until the log has at least $2 lines matching $1 (up to $3 s).
wait_for_log_count() {
    local pattern="$1" n="$2" t_end=$((SECONDS + $3))
    until [ "$(grep -c -- "$pattern" "$LOG" || true)" -ge "$n" ]; do
        kill -0 "$QPID" 2>/dev/null || fail "QEMU exited before $n lines \"$pattern\""
        [ "$SECONDS" -lt "$t_end" ] || fail "not $n lines \"$pattern\" from the board within $3 s"
        sleep 0.1
    done
}

# Boots the board; sets PTY.
boot_board() {
    step "boot the emulated board (QEMU mps2-an386, -icount shift=0, UART0 on a pty)"
    start_qemu "$ELF" -serial pty
    wait_for_log "char device redirected to" 10
    PTY="$(sed -n 's/.*char device redirected to \(\/dev\/pts\/[0-9]*\).*/\1/p' "$LOG" | head -1)"
    [ -n "$PTY" ] || fail "QEMU did not name its pty"
    # Keep the pty's slave side open for the whole run: while no process has it
    # open, QEMU's pty backend discards the guest's output and notices a new
    # reader only on its once-a-second poll. `wmr` flushes stale input on open.
    exec 3<>"$PTY"
    wait_for_log "^started:" "$QEMU_BOOT_TIMEOUT"
    echo "board up on $PTY (log: $LOG)"
}

boot_board

# Drives the robot on $1 as a user does; expects the handshake's chip $2,
# records to $3; sets `rec` (the record's JSON line) and `st` (the last status).
drive() {
    local port="$1" chip="$2" csv="$3"
    wmr() { "$WMR" --port "$port" --timeout-ms 2000 "$@"; }
    step "wmr status"
    st="$(wmr status)" || fail "wmr status: no answer from $chip"
    echo "$st"
    grep -q "robot: $chip " <<<"$st" || fail "the robot did not identify itself as $chip"
    grep -q "state Hold" <<<"$st" || fail "$chip did not boot in hold"
    step "wmr upload trajectories/square.toml"
    wmr upload "$ROOT/trajectories/square.toml" || fail "wmr upload ($chip)"
    step "wmr record --seconds $RECORD_S --arm (100 Hz telemetry)"
    rec="$(wmr record --seconds "$RECORD_S" --out "$csv" --arm --quiet)" || return 1
    echo "$rec"
    step "wmr disarm; wmr status"
    wmr disarm || fail "wmr disarm ($chip)"
    st="$(wmr status)" || fail "wmr status after the run ($chip)"
    echo "$st"
}

if ! drive "$PTY" mps2-an386-emu "$CSV"; then
    tail -n 5 "$LOG"
    fail "wmr record (mps2-an386-emu)"
fi
emu_rec="$rec"
# One more 1 s status line in the board's log (one second of virtual time:
# waited for, not guessed in wall time).
n_status="$(grep -c '^status ' "$LOG" || true)"
wait_for_log_count '^status ' $((n_status + 1)) "$EVENT_TIMEOUT"
cleanup

# The number after "KEY": in the JSON line $2 (default: the record's; "" when missing).
json() { sed -n "s/.*\"$1\":\([-0-9.eE+]*\).*/\1/p" <<<"${2:-$rec}"; }
# awk: |a - b| <= tol * b.
within_rel() { awk -v a="$1" -v b="$2" -v t="$3" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(d <= t * b) }'; }
# awk float comparison: le A B.
le() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a + 0 <= b + 0) }'; }

step "check (a): the run"
boots="$(grep -c '^==== trajectory-tracking firmware' "$LOG" || true)"
[ "$boots" -eq 1 ] || fail "the board booted $boots times (a watchdog reset?)"
if grep -E "^(WATCHDOG|PANIC|HARD FAULT|FATAL|SAFE STOP|unexpected interrupt)" "$LOG"; then
    fail "the board reported the fault above"
fi
grep -q "state Hold" <<<"$st" || fail "the board is not in hold after wmr disarm"
grep -q "stops: 0," <<<"$st" || fail "the runtime latched a stop during the run"
rows="$(json rows)"
dropped="$(json dropped_frames)"
[ -n "$rows" ] && [ -n "$dropped" ] || fail "no summary from wmr record"
min_rows=$((RECORD_S * 100 - 10))
[ "$rows" -ge "$min_rows" ] || fail "$rows telemetry rows recorded, expected >= $min_rows"
[ "$dropped" -le "$MAX_DROPPED_FRAMES" ] || fail "$dropped telemetry frames missing (> $MAX_DROPPED_FRAMES)"
echo "OK: $rows rows, $dropped frames missing, one boot, no fault, hold after disarm"

step "check (c): control tick instructions (-icount: SysTick counts instructions, resolution 40)"
# The 1 s status lines: key=value pairs. Max over the whole run; the mean
# over the seconds the robot was running (state: Running .. state: Hold).
read -r n_status late overruns mean_run max_all max_link link_ticks plant_max <<<"$(awk '
    /^state: Running/ { running = 1 }
    /^state: (Hold|Stopped|Stopping)/ { running = 0 }
    /^status / {
        for (i = 2; i <= NF; i++) { split($i, kv, "="); v[kv[1]] = kv[2] }
        n++; late = v["late"]; ovr = v["overruns"]
        if (v["insn_max"] > mx) mx = v["insn_max"]
        if (v["insn_max_link"] > ml) ml = v["insn_max_link"]
        if (v["plant_insn_max"] > pm) pm = v["plant_insn_max"]
        lt += v["link_ticks"]
        if (running) { nr++; sum += v["insn_mean"] }
    }
    END { printf "%d %d %d %d %d %d %d %d\n", n, late, ovr, nr ? sum / nr : 0, mx, ml, lt, pm }' "$LOG")"
[ "$n_status" -gt 0 ] || fail "no status lines in the board's log"
echo "over $n_status s: tick instructions mean $mean_run (while running), max $max_all, max with link traffic $max_link ($link_ticks ticks with link traffic)"
echo "plant step (outside the tick) max $plant_max instructions; late ticks $late, overrun episodes $overruns"
# Time is instructions (QEMU_ARGS): a tick started late only because the
# firmware's own work (ticks, link, plant) pushed it, never the host.
[ "$late" -eq 0 ] || fail "$late ticks started more than the overrun limit late ($overruns overrun episodes) although virtual time is the instruction count"
[ "$max_all" -lt "$TICK_BUDGET" ] || fail "worst tick $max_all instructions >= $TICK_BUDGET"
[ "$max_link" -lt "$TICK_BUDGET" ] || fail "worst tick with link traffic $max_link instructions >= $TICK_BUDGET"
[ "$max_link" -gt 0 ] || fail "no tick with link traffic was measured (the link statistics are blind)"
echo "OK: worst tick $max_all < $TICK_BUDGET instructions"

step "reference: hil-sim's runtime path behind the link, the same wmr commands"
start_device "$OUT_DIR" --scenario reference.toml
drive "$DEV_PTY" sim "$REF_CSV"
cleanup
ref_rec="$rec"

step "check (b): tracking the square, against hil-sim's runtime path"
rec="$emu_rec"
rms="$(json rms_pos_err_m)"
final="$(json final_pos_err_m)"
ref_rms="$(json rms_pos_err_m "$ref_rec")"
ref_final="$(json final_pos_err_m "$ref_rec")"
[ -n "$rms" ] && [ -n "$final" ] && [ -n "$ref_rms" ] && [ -n "$ref_final" ] ||
    fail "no metrics in wmr record's summaries"
printf '%-22s %10s %10s %12s %10s\n' "" "RMS [m]" "final [m]" "torque RMS" "saturated"
for who in emulated hil-sim; do
    r="$emu_rec"
    [ "$who" = hil-sim ] && r="$ref_rec"
    printf '%-22s %10.4f %10.4f %12.3f %10.3f\n' "$who" "$(json rms_pos_err_m "$r")" \
        "$(json final_pos_err_m "$r")" "$(json torque_rms_nm "$r")" "$(json saturated_fraction "$r")"
done
le "$rms" "$RMS_BOUND_M" || fail "RMS position error $rms m > $RMS_BOUND_M m: the robot does not follow the square"
within_rel "$rms" "$ref_rms" "$REL_TOL_RMS" ||
    fail "RMS position error $rms m differs from hil-sim's $ref_rms m by more than $REL_TOL_RMS of it"
within_rel "$final" "$ref_final" "$REL_TOL_FINAL" ||
    fail "final position error $final m differs from hil-sim's $ref_final m by more than $REL_TOL_FINAL of it"
echo "OK: RMS $rms m within $REL_TOL_RMS of hil-sim's $ref_rms m (and <= $RMS_BOUND_M m), final $final m within $REL_TOL_FINAL of $ref_final m"

if [ "$WATCHDOG_CHECK" = "1" ]; then
    step "check (d): the watchdog resets a stalled loop (negative control, feature stall-test)"
    LOG="$OUT_DIR/emu_stall_test.log"
    # -no-reboot: the watchdog's reset ends QEMU.
    start_qemu "$STALL_ELF" -serial null -no-reboot
    wait_for_log "^status" "$QEMU_BOOT_TIMEOUT"
    if grep -q "^WATCHDOG" "$LOG"; then
        fail "the watchdog fired before the stall"
    fi
    # The stall begins at 3 s of virtual time: up to 120 s of wall time.
    wait_for_log "^stall-test:" "$EVENT_TIMEOUT"
    wait_for_log "^WATCHDOG:" "$EVENT_TIMEOUT"
    t_end=$((SECONDS + EVENT_TIMEOUT))
    while kill -0 "$QPID" 2>/dev/null; do
        [ "$SECONDS" -lt "$t_end" ] || fail "the watchdog did not reset the board within $EVENT_TIMEOUT s of the stall"
        sleep 0.1
    done
    QPID=""
    grep -q "^status" "$LOG" || fail "the stall-test board never ran its loop"
    echo "OK: the loop stalled, the watchdog's NMI cut the motors, its reset ended QEMU (-no-reboot)"
fi

echo
echo "RESULT tick_insn_mean=$mean_run tick_insn_max=$max_all tick_insn_max_link=$max_link rms_pos_err_m=$rms final_pos_err_m=$final ref_rms_pos_err_m=$ref_rms ref_final_pos_err_m=$ref_final rows=$rows dropped=$dropped"
echo "emulated board: all checks passed in $((SECONDS - T_START)) s (CSV: $CSV, log: $OUT_DIR/emu.log)"
