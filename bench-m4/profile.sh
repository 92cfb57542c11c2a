#!/usr/bin/env bash
# Where the typical firmware tick's instructions go: runs bench-m4 under QEMU
# with a TCG plugin that counts instructions per address between the
# profile_start/profile_end markers around each typical tick (src/tick.rs),
# then attributes them to stages, functions and lines through the ELF's
# debug line tables (inlined frames). Approximate (LTO merges lines);
# bench-m4/run.sh gives the exact totals. Takes about a minute after the
# build. Needs gcc and llvm-symbolizer (apt-get install llvm).
# Usage: bench-m4/profile.sh [OUT_DIR]   (default target/profile)
set -euo pipefail
cd "$(dirname "$0")"
OUT="${1:-target/profile}"
mkdir -p "$OUT"
TARGET=thumbv7em-none-eabihf
cargo build --release --locked --bin bench-m4
ELF="target/$TARGET/release/bench-m4"
gcc -O2 -shared -fPIC -o "$OUT/libpchist.so" tools/qemu-pc-histogram.c
NM="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/llvm-nm"
addr() { "$NM" "$ELF" | awk -v f="$1" '$3 ~ f {print "0x" $1; exit}'; }
START="$(addr profile_start)"
END="$(addr profile_end)"
qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic -monitor none \
    -semihosting-config enable=on,target=native -icount shift=0,align=off,sleep=off \
    -kernel "$ELF" -plugin "$OUT/libpchist.so,start=$START,end=$END,out=$OUT/histogram.txt" \
    -d plugin > "$OUT/bench.txt"
grep '^RESULT' "$OUT/bench.txt"
python3 tools/profile.py "$ELF" "$OUT/histogram.txt" | tee "$OUT/profile.txt"
