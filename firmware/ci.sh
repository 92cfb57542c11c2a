#!/usr/bin/env bash
# Firmware build check: builds the release image for every supported chip,
# with and without the `imu` feature (MPU-6050 gyro), prints flash and
# static RAM use, and fails when any build exceeds the project's budget:
# 128 KiB flash, 32 KiB static RAM, on both chips, for every feature set
# (book/src/explanation/firmware.md, "Size" under "IMU").
#
# Then, on every image, the fault-entry check (issue 21 item 9): the first
# instructions of HardFault, NonMaskableInt, DefaultHandler, _defmt_panic
# and the panic handler, up to the end of their motor-off stores (the
# `dsb` that closes them, firmware/src/fault.rs), must not touch the stack
# (no push, no store or load through sp, no sub sp; the panic handler is
# allowed the compiler's frame prologue `push {r7, lr}; mov r7, sp`, see
# fault.rs), and must contain the seven motor-off stores, with the GPIOB
# mask of every bridge mode's lines (PB0, PB1, PB12-PB15: BSRR 0xF003 << 16,
# MODER outputs 0x55000005; firmware/src/motors.rs); the vector table's
# NMI and HardFault entries must be those symbols, and Reset must start by
# calling the board's __pre_init (the motor lines low before the RAM
# initialisation, firmware/src/board.rs; the same GPIOB mask). Negative control:
# the same check on a build with the `ci-fault-entry-pushes` feature (a
# push before the stores) must fail, or this script fails.
#
#   flash      = .vector_table + .text + .rodata + .data (the .data init image
#                is stored in flash too)
#   static RAM = .data + .bss + .uninit (the defmt RTT buffer lives in .uninit;
#                the stack is not static and not counted)
#
# Override the budgets to see the check fail: FW_FLASH_BUDGET=1000 ./ci.sh
# FW_NEGATIVE_CONTROL=0 skips the negative control's extra build.
set -euo pipefail
cd "$(dirname "$0")"

FLASH_BUDGET=${FW_FLASH_BUDGET:-131072}
RAM_BUDGET=${FW_RAM_BUDGET:-32768}
NEGATIVE_CONTROL=${FW_NEGATIVE_CONTROL:-1}
CHIPS=(stm32f411ce stm32f446re)
TARGET=thumbv7em-none-eabihf

# Tools this script uses.
if ! rustup target list --installed | grep -qx "$TARGET"; then
    rustup target add "$TARGET"
fi
if ! rustup component list --installed | grep -q '^llvm-tools'; then
    rustup component add llvm-tools
fi
if ! command -v flip-link >/dev/null 2>&1; then
    cargo install flip-link --locked
fi
HOST=$(rustc -vV | sed -n 's/^host: //p')
SIZE="$(rustc --print sysroot)/lib/rustlib/$HOST/bin/llvm-size"
[ -x "$SIZE" ] || { echo "llvm-size not found at $SIZE" >&2; exit 1; }
OBJDUMP="$(rustc --print sysroot)/lib/rustlib/$HOST/bin/llvm-objdump"
NM="$(rustc --print sysroot)/lib/rustlib/$HOST/bin/llvm-nm"
OBJCOPY="$(rustc --print sysroot)/lib/rustlib/$HOST/bin/llvm-objcopy"
[ -x "$OBJDUMP" ] && [ -x "$NM" ] && [ -x "$OBJCOPY" ] || { echo "llvm-objdump/llvm-nm/llvm-objcopy not found beside $SIZE" >&2; exit 1; }

# check_entry ELF SYMBOL PROLOGUE_OK: prints one line per entry; returns 1
# when the entry touches the stack before its motor-off stores end (the
# first `dsb`), or lacks them. PROLOGUE_OK=1 allows exactly the frame
# prologue `push {r7, lr}` / `mov r7, sp` as the first two instructions.
check_entry() {
    local elf=$1 sym=$2 prologue_ok=$3
    "$OBJDUMP" -d --no-show-raw-insn --disassemble-symbols="$sym" "$elf" | awk -v sym="$sym" -v pok="$prologue_ok" '
        /^[0-9a-f]+ </ { inside = 1; next }
        !inside || !/^ *[0-9a-f]+:/ { next }
        {
            sub(/^ *[0-9a-f]+:[ \t]*/, ""); sub(/[ \t]*@.*/, "")
            n++
            if ($0 ~ /^dsb/) { done = 1; exit }
            if (pok && n == 1 && $0 ~ /^push[ \t]+\{r7, lr\}$/) next
            if (pok && n == 2 && $0 ~ /^mov[ \t]+r7, sp$/) next
            if ($0 ~ /(^|[^a-z])sp([^a-z]|$)/ || $0 ~ /^(push|vpush|stm|pop|vpop)/) { bad = bad "\n        " $0 }
            if ($0 ~ /^str(\.w)?[ \t]+r[23], \[r1/) stores++
            if ($0 ~ /^movt[ \t]+r1, #0x4002$/) gpio++
            if ($0 ~ /^movt[ \t]+r1, #0x4001$/) tim1++
            if ($0 ~ /^movt[ \t]+r2, #0xf003$/) pbmask++
            if ($0 ~ /^movt[ \t]+r2, #0x5500$/) pbmode++
        }
        END {
            if (!n) { printf "    %s: not found\n", sym; exit 1 }
            if (!done) { printf "    %s: no motor-off sequence (no dsb)\n", sym; exit 1 }
            if (bad != "") { printf "    %s: touches the stack before the motor-off stores:%s\n", sym, bad; exit 1 }
            if (stores < 7 || gpio < 2 || tim1 < 1) { printf "    %s: %d motor-off stores (GPIO %d, TIM1 %d), expected 7 (2, 1)\n", sym, stores, gpio, tim1; exit 1 }
            if (!pbmask || !pbmode) { printf "    %s: GPIOB reset mask 0xF003 (PB0, PB1, PB12-PB15) or its MODER outputs (0x55000005) missing: a bridge mode'"'"'s line is left driven\n", sym; exit 1 }
            printf "    %s: %d stores to GPIOB/TIM1/GPIOA before any stack access, every bridge mode'"'"'s lines (PB0, PB1, PB12-PB15, PA8, PA9)%s\n", sym, stores, pok ? " (after the frame prologue)" : ""
        }'
}

# check_fault_entries ELF: every entry; returns 1 when any fails.
check_fault_entries() {
    local elf=$1 ok=0 panic_sym
    for sym in HardFault NonMaskableInt DefaultHandler _defmt_panic; do
        check_entry "$elf" "$sym" 0 || ok=1
    done
    # The vector table's NMI (word 2) and HardFault (word 3) entries are
    # the checked symbols (Thumb bit set), not cortex-m-rt's defaults.
    local vt words want
    vt=$(mktemp)
    "$OBJCOPY" -O binary --only-section=.vector_table "$elf" "$vt"
    read -r -a words < <(od -An -tx4 -N16 "$vt")
    rm -f "$vt"
    for pair in 2:NonMaskableInt 3:HardFault; do
        want=$("$NM" "$elf" | awk -v s="${pair#*:}" '$3 == s { print $1; exit }')
        [ -n "$want" ] && want=$(printf '%08x' $((0x$want + 1)))
        if [ "${words[${pair%%:*}]:-}" != "$want" ]; then
            echo "    vector ${pair%%:*} is 0x${words[${pair%%:*}]:-none}, not ${pair#*:} (0x$want)"
            ok=1
        else
            echo "    vector ${pair%%:*} -> ${pair#*:} (0x$want)"
        fi
    done
    # Reset's first instruction calls the board's __pre_init (motor lines
    # low before the RAM initialisation), not cortex-m-rt's empty default,
    # and __pre_init does not use the stack.
    local first pre def pre_dis
    first=$("$OBJDUMP" -d --no-show-raw-insn --disassemble-symbols=Reset "$elf" | awk '/^ *[0-9a-f]+:/ { print; exit }')
    pre=$("$NM" "$elf" | awk '$3 == "__pre_init" { print $1; exit }')
    def=$("$NM" "$elf" | awk '$3 == "DefaultPreInit" { print $1; exit }')
    if ! grep -q "bl.*<__pre_init>" <<<"$first" || [ -z "$pre" ] || [ "$pre" = "$def" ]; then
        echo "    Reset does not start with the board's __pre_init (first: ${first:-none})"
        ok=1
    elif "$OBJDUMP" -d --no-show-raw-insn --disassemble-symbols=__pre_init "$elf" |
        awk '/^ *[0-9a-f]+:/' | grep -Eq '(^|[^a-z])sp([^a-z]|$)|	(push|pop|stm)'; then
        echo "    __pre_init uses the stack"
        ok=1
    elif pre_dis=$("$OBJDUMP" -d --no-show-raw-insn --disassemble-symbols=__pre_init "$elf") &&
        { ! grep -q 'movt.*#0xf003' <<<"$pre_dis" || ! grep -q 'movt.*#0x5500' <<<"$pre_dis"; }; then
        echo "    __pre_init does not reset and drive every bridge mode's GPIOB line (mask 0xF003, MODER 0x55000005)"
        ok=1
    else
        echo "    Reset -> __pre_init (0x$pre): motor lines low before the RAM initialisation"
    fi
    panic_sym=$("$NM" "$elf" | awk '$3 ~ /rust_begin_unwind/ { print $3; exit }')
    if [ -z "$panic_sym" ]; then
        echo "    panic handler (rust_begin_unwind): not found"
        ok=1
    else
        check_entry "$elf" "$panic_sym" 1 || ok=1
    fi
    return $ok
}

status=0
# Every image is built in one target directory, BUILD_DIR: what does not
# depend on the chip or the feature set (the proc-macros, defmt, embassy's
# executor, controller-core, ...: about 85 % of a cold build's CPU time) is
# compiled once, and cargo keeps each feature set's crates beside the
# others', so switching back rebuilds nothing. Each image is copied out to
# its own directory right after its build: target/ci-CHIP[-imu]/$TARGET/
# release/firmware (the paths stm32-emu and the docs use).
BUILD_DIR=target/ci-build
BUILD_ELF="$BUILD_DIR/$TARGET/release/firmware"
# fw_build FEATURES: one release image at $BUILD_ELF.
fw_build() {
    cargo build --release --locked --no-default-features --features "$1" \
        --target "$TARGET" --target-dir "$BUILD_DIR"
}

# build_and_size LABEL FEATURES OUT_DIR ENFORCE: release build (copied to
# OUT_DIR), section sizes, flash/RAM sums; ENFORCE=1 fails the run beyond
# the budget, ENFORCE=0 only reports.
build_and_size() {
    local label=$1 features=$2 dir=$3 enforce=$4
    echo "==> building firmware: $label (features $features)"
    fw_build "$features"
    mkdir -p "$dir/$TARGET/release"
    cp "$BUILD_ELF" "$dir/$TARGET/release/firmware"
    local elf="$dir/$TARGET/release/firmware" flash ram
    read -r flash ram < <("$SIZE" -A "$elf" | awk '
        $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { f += $2 }
        $1 == ".data" { f += $2; r += $2 }
        $1 == ".bss" || $1 == ".uninit" { r += $2 }
        END { print f + 0, r + 0 }')
    "$SIZE" -A "$elf" | awk '$1 ~ /^\.(vector_table|text|rodata|data|bss|uninit)$/ { printf "    %-14s %7d\n", $1, $2 }'
    awk -v c="$label" -v f="$flash" -v r="$ram" \
        'BEGIN { printf "    %s: flash %d B (%.1f KiB), static RAM %d B (%.1f KiB)\n", c, f, f / 1024, r, r / 1024 }'
    if [ "$enforce" -ne 1 ]; then
        echo "    (size reported only; not checked against the budget)"
        return
    fi
    local ok=1
    if [ "$flash" -gt "$FLASH_BUDGET" ]; then
        echo "FAIL: $label flash $flash B exceeds budget $FLASH_BUDGET B" >&2
        status=1; ok=0
    fi
    if [ "$ram" -gt "$RAM_BUDGET" ]; then
        echo "FAIL: $label static RAM $ram B exceeds budget $RAM_BUDGET B" >&2
        status=1; ok=0
    fi
    if [ "$ok" -eq 1 ]; then
        echo "    budget OK (flash <= $FLASH_BUDGET B, static RAM <= $RAM_BUDGET B)"
    fi
    echo "    fault entries (motors off before the stack):"
    if ! check_fault_entries "$elf"; then
        echo "FAIL: $label: a fault or panic entry touches the stack before cutting the motors" >&2
        status=1
    fi
}

for chip in "${CHIPS[@]}"; do
    build_and_size "$chip" "$chip" "target/ci-$chip" 1
    build_and_size "$chip + imu" "$chip,imu" "target/ci-$chip-imu" 1
done

# Negative control of the fault-entry check: a push before the stores must
# be caught. Built last in BUILD_DIR (only this crate rebuilds) and not
# copied out: $BUILD_ELF is the defective image afterwards (never flash it).
if [ "$NEGATIVE_CONTROL" = "1" ]; then
    echo "==> negative control: fault entries that push first (feature ci-fault-entry-pushes)"
    fw_build stm32f411ce,ci-fault-entry-pushes
    if check_fault_entries "$BUILD_ELF"; then
        echo "FAIL: the fault-entry check passed a handler that pushes first" >&2
        status=1
    else
        echo "    OK: the check rejects it (the lines above)"
    fi
fi
exit "$status"
