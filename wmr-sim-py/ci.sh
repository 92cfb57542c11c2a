#!/usr/bin/env bash
# CI step of the Python package wmrsim (issue 36, book/src/how-to/python.md): the
# wheel built with maturin, installed into a venv of pinned versions (made
# anew on a fresh clone), then in a private network namespace (Ray's
# servers see only the loopback): pytest over the API (bad input
# included), equality with the hil-sim CLI of the test step, a Monte-Carlo
# and a tuning generation over a local 2-CPU Ray cluster, and the worked
# example of book/src/how-to/python.md (the wheel-radius sweep plotted with
# matplotlib). Run after `cargo test --release --workspace`: it uses
# target/release/hil-sim, and maturin reuses hil-sim's build (D161).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
cd "$ROOT"
FAIL_PREFIX="wmrsim: "
. scripts/check-lib.sh

VENV="${WMRSIM_VENV:-$ROOT/target/wmrsim-venv}"
WHEELS="$ROOT/target/wheels-py"

if [ -z "${WMRSIM_IN_NETNS:-}" ]; then
    # Exact versions (../shared/TOOLCHAIN.md); the venv is made anew when any differs.
    PINS="maturin==1.16.0 numpy==2.4.6 pytest==9.2.0 pandas==3.1.1 matplotlib==3.11.2 ray==2.60.0"
    want=$(echo "$PINS" | tr ' ' '\n' | sort | tr '\n' ' ')
    have=$("$VENV/bin/python" -c 'import importlib.metadata as m
names = ["maturin", "numpy", "pytest", "pandas", "matplotlib", "ray"]
print(" ".join(sorted(f"{n}=={m.version(n)}" for n in names)) + " ")' 2>/dev/null || true)
    if [ "$have" != "$want" ]; then
        rm -rf "$VENV"
        python3 -m venv "$VENV" || fail "python3 -m venv (apt-get install python3-venv)"
        t0=$SECONDS
        # shellcheck disable=SC2086
        "$VENV/bin/pip" install --quiet $PINS || fail "pip install $PINS"
        echo "venv: pip install of $PINS took $((SECONDS - t0)) s"
    fi
    step "wheel (maturin build --release)"
    rm -f "$WHEELS"/wmrsim-*.whl
    "$VENV/bin/maturin" build --release --quiet -m wmr-sim-py/Cargo.toml --out "$WHEELS" \
        -i "$VENV/bin/python" || fail "maturin build"
    "$VENV/bin/pip" install --quiet --force-reinstall --no-deps "$WHEELS"/wmrsim-*.whl ||
        fail "pip install the wheel"
    test -x target/release/hil-sim || cargo build --release -p hil-sim
    if ! command -v ip >/dev/null; then
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq iproute2 ||
            fail "apt-get install iproute2 (the namespace's loopback needs ip)"
    fi
    exec unshare -n bash -c "ip link set lo up && WMRSIM_IN_NETNS=1 bash '$0'"
fi

# --- inside the private network namespace ---
PY="$VENV/bin/python"
OUT="$(mktemp -d)"
export HIL_SIM="$ROOT/target/release/hil-sim" WMRSIM_REQUIRE_RAY=1
step "pytest: the API, equality with the hil-sim CLI, Ray (2 CPUs, loopback)"
# From outside the source tree: the installed wheel is what is imported.
(cd "$OUT" && "$PY" -m pytest -q -p no:cacheprovider "$ROOT/wmr-sim-py/tests") || fail "pytest"
step "book/src/how-to/python.md's worked example: wheel-radius mismatch sweep (matplotlib)"
(cd "$OUT" && "$PY" "$ROOT/wmr-sim-py/examples/wheel_radius_sweep.py" --duration 15 --seeds 1 \
    --out "$OUT/wheel_radius_sweep.png") || fail "examples/wheel_radius_sweep.py"
test -s "$OUT/wheel_radius_sweep.png" || fail "no figure written"
step "Ray example: Monte-Carlo and a tuning generation on a local cluster"
(cd "$OUT" && "$PY" "$ROOT/wmr-sim-py/examples/ray_sweeps.py" --cpus 2 --runs 6 --blocks 3 \
    --population 4 --duration 5) || fail "examples/ray_sweeps.py"
echo "wmrsim: all passed ($OUT)"
