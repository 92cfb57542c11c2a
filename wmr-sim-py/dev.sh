#!/usr/bin/env bash
# Development loop: rebuild the wheel into target/wheels-py and install it
# into the venv target/wmrsim-venv (made by ci.sh).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
cd "$ROOT"
rm -f target/wheels-py/wmrsim-*.whl
target/wmrsim-venv/bin/maturin build --release -m wmr-sim-py/Cargo.toml --out target/wheels-py -i target/wmrsim-venv/bin/python --quiet
target/wmrsim-venv/bin/pip install --quiet --force-reinstall --no-deps target/wheels-py/wmrsim-*.whl
