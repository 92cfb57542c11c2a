#!/usr/bin/env bash
# Side-by-side speed of the current tree against a baseline commit, on this
# machine, in one run (issue 17, "Speed"):
#
#   * single run: `hil-sim bench`'s median time of one 40 s paper Case 2 run
#     with the proposed controller (and its floor line),
#   * Monte-Carlo: `hil-sim montecarlo --runs $MC_RUNS --case 2` throughput
#     [simulations/s].
#
# The baseline (default eb68ee7, "today's build" of issue 17; override with
# BASE=<commit> or the first argument) is built in a temporary `git worktree`
# under /tmp with its own target dir; both are kept and reused by later runs.
# The current tree is built in its own target/. The two binaries then run
# alternately (A B, B A, A B, ...) $REPS times and the medians and their
# ratios (current / baseline speed) are printed. A benchmark that prints
# numbers, not a timed test: on a shared machine expect noise; the
# alternation and the medians make the ratio the robust figure (on a loaded
# machine the median of each bench's fastest run is the steadier one).
#
# Usage: hil-sim/bench-ratio.sh [BASE]
#   env: BASE (eb68ee7), REPS (5), MC_RUNS (200), BENCH_REPS (9, `bench --reps`),
#        WORK (/tmp/wmr-bench-ratio: worktree, target dir, binaries),
#        PROFILE (release: the cargo profile the current tree is built with),
#        CUR_BIN / BASE_BIN (prebuilt binaries to compare instead of building)
set -euo pipefail

BASE=${1:-${BASE:-eb68ee7}}
REPS=${REPS:-5}
MC_RUNS=${MC_RUNS:-200}
BENCH_REPS=${BENCH_REPS:-9}
WORK=${WORK:-/tmp/wmr-bench-ratio}
PROFILE=${PROFILE:-release}
REPO=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
BASE_SHA=$(git -C "$REPO" rev-parse --verify "$BASE^{commit}") || {
    echo "bench-ratio: baseline '$BASE' is not a commit of $REPO" >&2
    exit 2
}
BASE_TREE=$WORK/base-$BASE_SHA
BASE_TARGET=$WORK/base-target
mkdir -p "$WORK"

# --- baseline: worktree (reused) and its own target dir (reused) -----------
if [ ! -e "$BASE_TREE/Cargo.toml" ]; then
    git -C "$REPO" worktree prune
    git -C "$REPO" worktree add --detach "$BASE_TREE" "$BASE_SHA" >&2
fi
if [ ! -d "$BASE_TARGET" ] && [ -d "$REPO/target/release/deps" ]; then
    # Seed the third-party dependencies (keyed by version, not path) from
    # the current tree's build: saves a cold build of clap, plotters, ...
    mkdir -p "$BASE_TARGET"
    cp -r "$REPO/target/release" "$BASE_TARGET/release"
fi
B=$WORK/hil-sim-current
if [ -n "${CUR_BIN:-}" ]; then
    # A prebuilt current binary (e.g. another profile's): no build.
    [ -x "$CUR_BIN" ] || { echo "bench-ratio: CUR_BIN '$CUR_BIN' is not executable" >&2; exit 2; }
    cp "$CUR_BIN" "$B"
else
    echo "bench-ratio: building current tree $REPO (profile $PROFILE)" >&2
    (cd "$REPO" && cargo build --profile "$PROFILE" --quiet -p hil-sim)
    cp "$REPO/target/$PROFILE/hil-sim" "$B"
fi
A=$WORK/hil-sim-base
if [ -n "${BASE_BIN:-}" ]; then
    [ -x "$BASE_BIN" ] || { echo "bench-ratio: BASE_BIN '$BASE_BIN' is not executable" >&2; exit 2; }
    [ "$BASE_BIN" -ef "$A" ] || cp "$BASE_BIN" "$A"
else
    echo "bench-ratio: building baseline $BASE_SHA in $BASE_TREE" >&2
    (cd "$BASE_TREE" && cargo build --release --quiet -p hil-sim --target-dir "$BASE_TARGET")
    cp "$BASE_TARGET/release/hil-sim" "$A"
fi
CUR_DESC="$(git -C "$REPO" rev-parse --short HEAD)$(git -C "$REPO" diff --quiet HEAD -- . ':!target' || echo '+dirty')"
[ -n "${CUR_BIN:-}" ] && CUR_DESC="$CUR_DESC (binary $CUR_BIN)"
[ "$PROFILE" != release ] && CUR_DESC="$CUR_DESC (profile $PROFILE)"

# --- one measurement each ----------------------------------------------------
# bench: prints "proposed  <median ms> <min ms> <traced ms> <ns> ns" and
# "proposed   floor  <ns> ns, full loop  <ns> ns (...)".
bench_once() { # binary -> "median_ms min_ms floor_ns"
    local out
    out=$("$1" bench --reps "$BENCH_REPS" --mc-runs 4 2>&1)
    local med min floor
    med=$(awk '$1 == "proposed" && $2 ~ /^[0-9.]+$/ { print $2; exit }' <<<"$out")
    min=$(awk '$1 == "proposed" && $2 ~ /^[0-9.]+$/ { print $3; exit }' <<<"$out")
    floor=$(awk '$1 == "proposed" && $2 == "floor" { print $3; exit }' <<<"$out")
    [ -n "$med" ] && [ -n "$min" ] && [ -n "$floor" ] || {
        echo "bench-ratio: cannot parse '$1 bench' output:" >&2
        echo "$out" >&2
        exit 1
    }
    echo "$med $min $floor"
}
mc_once() { # binary -> runs/s
    local out rate
    out=$("$1" montecarlo --runs "$MC_RUNS" --case 2 2>/dev/null)
    rate=$(sed -n 's/.* \([0-9.]*\) runs\/s$/\1/p' <<<"$out" | tail -1)
    [ -n "$rate" ] || {
        echo "bench-ratio: cannot parse '$1 montecarlo' output:" >&2
        echo "$out" >&2
        exit 1
    }
    echo "$rate"
}
median() { sort -g | awk '{ v[NR] = $1 } END { if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

declare -a a_ms b_ms a_min b_min a_floor b_floor a_mc b_mc
printf '%-4s %-9s %14s %10s %11s %12s\n' rep binary "proposed [ms]" "min [ms]" "floor [ns]" "MC [runs/s]" >&2
for ((i = 0; i < REPS; i++)); do
    order=(A B)
    ((i % 2)) && order=(B A)
    for w in "${order[@]}"; do
        bin=$A
        [ "$w" = B ] && bin=$B
        read -r ms mn fl < <(bench_once "$bin")
        mc=$(mc_once "$bin")
        if [ "$w" = A ]; then
            a_ms+=("$ms"); a_min+=("$mn"); a_floor+=("$fl"); a_mc+=("$mc")
            name=baseline
        else
            b_ms+=("$ms"); b_min+=("$mn"); b_floor+=("$fl"); b_mc+=("$mc")
            name=current
        fi
        printf '%-4s %-9s %14s %10s %11s %12s\n' "$i" "$name" "$ms" "$mn" "$fl" "$mc" >&2
    done
done

med() { printf '%s\n' "$@" | median; }
am=$(med "${a_ms[@]}"); bm=$(med "${b_ms[@]}")
an=$(med "${a_min[@]}"); bn=$(med "${b_min[@]}")
af=$(med "${a_floor[@]}"); bf=$(med "${b_floor[@]}")
ac=$(med "${a_mc[@]}"); bc=$(med "${b_mc[@]}")
steps=40000
echo "side by side on $(hostname) ($(nproc) cores), $REPS alternated repetitions, medians:"
echo "baseline $BASE_SHA vs current $CUR_DESC"
awk -v am="$am" -v bm="$bm" -v an="$an" -v bn="$bn" -v af="$af" -v bf="$bf" -v ac="$ac" -v bc="$bc" -v n="$steps" 'BEGIN {
    printf "%-34s %12s %12s %8s\n", "", "baseline", "current", "ratio"
    printf "%-34s %12.2f %12.2f %7.2fx\n", "single run, proposed [ms]", am, bm, am / bm
    printf "%-34s %12.0f %12.0f\n", "  per control period [ns]", am * 1e6 / n, bm * 1e6 / n
    printf "%-34s %12.2f %12.2f %7.2fx\n", "  fastest of each bench [ms]", an, bn, an / bn
    printf "%-34s %12.0f %12.0f %7.2fx\n", "  floor (ref + plant + ctrl) [ns]", af, bf, af / bf
    printf "%-34s %12.2f %12.2f\n", "  full loop / floor", am * 1e6 / n / af, bm * 1e6 / n / bf
    printf "%-34s %12.1f %12.1f %7.2fx\n", "Monte-Carlo --runs '"$MC_RUNS"' [runs/s]", ac, bc, bc / ac
}'
