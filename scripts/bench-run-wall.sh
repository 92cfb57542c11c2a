#!/usr/bin/env bash
# Wall time against CPU time of one `hil-sim run` (issue 30): the run's
# helper threads (progress) must not make it wait. Prints, for each binary
# given (default: this checkout's target/release/hil-sim), the median over
# --reps runs of the wall time, the CPU time (user + system) and their
# ratio, side by side, so an older build can be named and measured on the
# same machine in the same session:
#
#   scripts/bench-run-wall.sh [--reps N] [--args "RUN ARGS"] [BIN ...]
#
# A benchmark that prints numbers, never a test: nothing here fails on a
# slow or loaded machine (it fails only when a binary does).
set -euo pipefail
cd "$(dirname "$0")/.."

reps=21
run_args="--duration 20 --sensing mocap"
bins=()
while [ $# -gt 0 ]; do
    case "$1" in
        --reps) reps="$2"; shift 2 ;;
        --args) run_args="$2"; shift 2 ;;
        -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
        *) bins+=("$1"); shift ;;
    esac
done
[ "${#bins[@]}" -gt 0 ] || bins=(target/release/hil-sim)

median() { sort -g | awk '{a[NR]=$1} END {print (NR%2) ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2}'; }

printf 'hil-sim run %s, %d runs each, stderr to a pipe; medians\n' "$run_args" "$reps"
printf '%-48s %10s %10s %10s\n' binary "wall [ms]" "CPU [ms]" "wall/CPU"
for bin in "${bins[@]}"; do
    [ -x "$bin" ] || { echo "error: $bin is not an executable (build it first: cargo build --release -p hil-sim)" >&2; exit 1; }
    walls=(); cpus=(); ratios=()
    for _ in $(seq "$reps"); do
        # bash's `time` reports the child's wall, user and system seconds.
        t=$( { TIMEFORMAT='%R %U %S'; time "$bin" run $run_args >/dev/null 2> >(cat >/dev/null); } 2>&1 )
        read -r wall user sys <<<"$t"
        cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN {print u + s}')
        walls+=("$wall"); cpus+=("$cpu")
        ratios+=("$(awk -v w="$wall" -v c="$cpu" 'BEGIN {print (c > 0) ? w / c : 0}')")
    done
    w=$(printf '%s\n' "${walls[@]}" | median)
    c=$(printf '%s\n' "${cpus[@]}" | median)
    r=$(printf '%s\n' "${ratios[@]}" | median)
    printf '%-48s %10.1f %10.1f %10.2f\n' "$bin" "$(awk -v x="$w" 'BEGIN {print 1000 * x}')" \
        "$(awk -v x="$c" 'BEGIN {print 1000 * x}')" "$r"
done
