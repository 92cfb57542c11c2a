#!/usr/bin/env bash
# Cortex-M4F benchmark check (issue 5). Builds bench-m4 for
# thumbv7em-none-eabihf, runs it under QEMU mps2-an386 with -icount, prints the
# table, and fails (non-zero) if
#   (a) the control-step ELF (step-only: reference sampling + Controller::step
#       of all three kinds, no printing) links an f64 soft-float routine
#       (__aeabi_d*, __adddf3, ...) or formatting code (core::fmt, flt2dec), or
#   (b) the proposed step exceeds PROPOSED_BUDGET instructions (default 1500)
#       in its worst observed step (SysTick resolution: 40 instructions),
#   (c) the worst firmware tick with an external pose correction (mocap, and
#       UWB at the maximal 250 ms latency: update + re-propagation slice, or
#       a tick continuing one) reaches CORRECTION_BUDGET (default 20000:
#       20 % of a 1 ms period at 100 MHz),
#   (d) the typical firmware tick (LoopTimer::tick + ControlLoop::tick with
#       reference, proposed step, pacer, estimator prediction; no pose
#       measurement, no re-propagation pending) exceeds TICK_BUDGET
#       (default 3000) in its mean or max. The target of issues 9 and 12
#       is 1500; measured 2866 mean / 2956 max (BENCHMARKS.md, "Tick
#       cost"), so this check holds the line at today's cost until the
#       tick is reworked (bench-m4/profile.sh shows where it goes).
# (a) has negative controls: the libm build of step-only must be flagged,
# and the bench binary (which prints) must show core::fmt; (b)-(d) one:
# the same comparison with a budget one below the measured value must fail.
#
# Usage: bench-m4/run.sh            (from anywhere; installs what it needs)
# Env:   PROPOSED_BUDGET=1500  CORRECTION_BUDGET=20000  TICK_BUDGET=3000
#        QEMU_TIMEOUT=600  SKIP_NEGATIVE_CONTROLS=1
set -euo pipefail
cd "$(dirname "$0")"

BUDGET="${PROPOSED_BUDGET:-1500}"
CORRECTION_BUDGET="${CORRECTION_BUDGET:-20000}"
TICK_BUDGET="${TICK_BUDGET:-3000}"
QEMU_TIMEOUT="${QEMU_TIMEOUT:-600}"
TARGET=thumbv7em-none-eabihf

step() { printf '\n== %s\n' "$*"; }

step "tools"
if ! command -v qemu-system-arm >/dev/null 2>&1; then
    SUDO=""
    if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
    $SUDO apt-get update
    $SUDO apt-get install -y qemu-system-arm
fi
rustup target add "$TARGET" >/dev/null
rustup component add llvm-tools >/dev/null
HOST="$(rustc -vV | sed -n 's/^host: //p')"
NM="$(rustc --print sysroot)/lib/rustlib/$HOST/bin/llvm-nm"
SIZE="$(rustc --print sysroot)/lib/rustlib/$HOST/bin/llvm-size"
[ -x "$NM" ] || { echo "llvm-nm not found at $NM" >&2; exit 1; }
echo "machine: $(uname -m); $(qemu-system-arm --version | head -1); $(rustc --version); date: $(date -u +%Y-%m-%dT%H:%MZ)"

step "build (release)"
cargo build --release --locked --bins
REL="target/$TARGET/release"

# f64 soft-float: __aeabi_dadd/dmul/d2f/f2d/i2d..., __adddf3, __extendsfdf2,
# __fixdfsi, __floatsidf...; formatting: core::fmt, float formatting (flt2dec).
DOUBLE_RE='(^| )(__aeabi_(d[a-z0-9]+|f2d|[a-z]*2d)|__[a-z]+df[0-9a-z]*)$'
FMT_RE='core::fmt|flt2dec|dec2flt'

# Prints offending symbols of ELF $1; returns 0 if it is clean.
clean_elf() {
    local bad
    bad="$("$NM" -C "$1" | grep -E "$DOUBLE_RE|$FMT_RE" || true)"
    if [ -n "$bad" ]; then
        echo "$bad" | head -20
        return 1
    fi
    return 0
}

step "check (a): no f64 soft-float and no formatting code in the control step"
if clean_elf "$REL/step-only"; then
    echo "OK: $REL/step-only links no __aeabi_d*/__*df* routine and no core::fmt"
    "$SIZE" "$REL/step-only"
else
    echo "FAIL: the control step links the symbols above" >&2
    exit 1
fi

if [ -z "${SKIP_NEGATIVE_CONTROLS:-}" ]; then
    step "negative controls for check (a)"
    cargo build --release --locked --bin step-only --features accurate-math \
        --target-dir target/accurate
    if clean_elf "target/accurate/$TARGET/release/step-only" >/dev/null; then
        echo "FAIL: the libm (accurate-math) build should link f64 routines; the check is blind" >&2
        exit 1
    fi
    echo "OK: the libm build is flagged ($("$NM" "target/accurate/$TARGET/release/step-only" | grep -cE "$DOUBLE_RE") f64 routines)"
    if clean_elf "$REL/bench-m4" >/dev/null; then
        echo "FAIL: the printing bench binary should link core::fmt; the check is blind" >&2
        exit 1
    fi
    echo "OK: the printing bench binary is flagged (core::fmt present)"
fi

# -icount shift=5: 32 ns of virtual time per instruction against SysTick's
# 40 ns (25 MHz), so one count is 1.25 instructions. With shift=0 a count
# was 40 instructions, and a max read 2,996 that was 3,007-3,012 (D215).
step "run under QEMU mps2-an386 (-icount shift=${ICOUNT_SHIFT:-5}: SysTick counts 1.25 instructions)"
OUT="$(mktemp)"
trap 'rm -f "$OUT"' EXIT
set +e
timeout "$QEMU_TIMEOUT" qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic \
    -monitor none -semihosting-config enable=on,target=native \
    -icount shift=${ICOUNT_SHIFT:-5},align=off,sleep=off -kernel "$REL/bench-m4" | tee "$OUT"
rc=${PIPESTATUS[0]}
set -e
if [ "$rc" -ne 0 ]; then
    echo "FAIL: bench-m4 exited with $rc under QEMU (124 = timeout)" >&2
    exit 1
fi

line="$(grep '^RESULT ' "$OUT" || true)"
# The value of KEY in the RESULT line ("" when missing).
result() { sed -n "s/.* $1=\([0-9]*\).*/\1/p" <<<"$line"; }
# within BUDGET VALUE...: every VALUE <= BUDGET.
within() {
    local b="$1" v
    shift
    for v in "$@"; do [ "$v" -le "$b" ] || return 1; done
}
# The negative control of a budget check: one below the largest value fails.
control() {
    [ -n "${SKIP_NEGATIVE_CONTROLS:-}" ] && return 0
    local m
    m="$(printf '%s\n' "$@" | sort -n | tail -1)"
    if within "$((m - 1))" "$@"; then
        echo "FAIL: negative control: budget $((m - 1)) was not flagged; the check is blind" >&2
        exit 1
    fi
    echo "OK: negative control: budget $((m - 1)) is flagged"
}
mean="$(result proposed_step_mean)"
max="$(result proposed_step_max)"
tmean="$(result tick_typical_mean)"
tmax="$(result tick_typical_max)"
cmax="$(result tick_correction_max)"
if [ -z "$mean" ] || [ -z "$max" ] || [ -z "$tmean" ] || [ -z "$tmax" ] || [ -z "$cmax" ]; then
    echo "FAIL: no complete RESULT line from bench-m4" >&2
    exit 1
fi

step "check (b): proposed step <= $BUDGET instructions"
if ! within "$BUDGET" "$mean" "$max"; then
    echo "FAIL: proposed step mean $mean, max $max instructions > budget $BUDGET" >&2
    exit 1
fi
echo "OK: proposed step mean $mean, max $max instructions <= $BUDGET"
control "$mean" "$max"

step "check (c): worst tick with a pose correction < $CORRECTION_BUDGET instructions"
if ! within "$((CORRECTION_BUDGET - 1))" "$cmax"; then
    echo "FAIL: worst tick with a correction $cmax instructions >= budget $CORRECTION_BUDGET" >&2
    exit 1
fi
echo "OK: worst tick with a correction $cmax instructions < $CORRECTION_BUDGET"
control "$cmax"

step "check (d): typical firmware tick <= $TICK_BUDGET instructions"
if ! within "$TICK_BUDGET" "$tmean" "$tmax"; then
    echo "FAIL: typical tick mean $tmean, max $tmax instructions > budget $TICK_BUDGET" >&2
    exit 1
fi
echo "OK: typical tick mean $tmean, max $tmax instructions <= $TICK_BUDGET"
control "$tmean" "$tmax"
