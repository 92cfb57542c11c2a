#!/usr/bin/env bash
# Firmware build check: builds the release image for every supported chip,
# prints flash and static RAM use, and fails when any chip exceeds the
# budget of issue 10: 64 KiB flash, 16 KiB static RAM per chip, with the
# host link, the pose estimator and the governor (firmware/README.md, "Size").
# Then the same with the `imu` feature (MPU-6050 gyro): size reported for
# every chip, budget checked on the F446RE (IMU_CHECKED below).
#
#   flash      = .vector_table + .text + .rodata + .data (the .data init image
#                is stored in flash too)
#   static RAM = .data + .bss + .uninit (the defmt RTT buffer lives in .uninit;
#                the stack is not static and not counted)
#
# Override the budgets to see the check fail: FW_FLASH_BUDGET=1000 ./ci.sh
set -euo pipefail
cd "$(dirname "$0")"

FLASH_BUDGET=${FW_FLASH_BUDGET:-65536}
RAM_BUDGET=${FW_RAM_BUDGET:-16384}
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

status=0
# build_and_size LABEL FEATURES TARGET_DIR ENFORCE: release build, section
# sizes, flash/RAM sums; ENFORCE=1 fails the run beyond the budget,
# ENFORCE=0 only reports.
build_and_size() {
    local label=$1 features=$2 dir=$3 enforce=$4
    echo "==> building firmware: $label (features $features)"
    cargo build --release --locked --no-default-features --features "$features" \
        --target "$TARGET" --target-dir "$dir"
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
}

for chip in "${CHIPS[@]}"; do
    # One target dir per chip and feature set: switching the chip feature
    # would otherwise rebuild embassy-stm32 on every run.
    build_and_size "$chip" "$chip" "target/ci-$chip" 1
done
# The IMU (`imu` feature, off by default) on each chip: checked against
# the budget on the chips listed in IMU_CHECKED, reported on the others
# (the F411CE has no flash to spare for it, firmware/README.md "IMU").
IMU_CHECKED=(stm32f446re)
for chip in "${CHIPS[@]}"; do
    enforce=0
    for c in "${IMU_CHECKED[@]}"; do [ "$c" = "$chip" ] && enforce=1; done
    build_and_size "$chip + imu" "$chip,imu" "target/ci-$chip-imu" "$enforce"
done
exit "$status"
