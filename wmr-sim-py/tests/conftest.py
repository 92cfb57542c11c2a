"""Shared fixtures of the wmrsim tests: the repository's root and the
`hil-sim` binary the CLI comparisons run (HIL_SIM, else target/release)."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def root() -> pathlib.Path:
    return ROOT


@pytest.fixture(scope="session")
def hil_sim():
    """A function running the hil-sim CLI; returns its stdout."""
    exe = os.environ.get("HIL_SIM", str(ROOT / "target" / "release" / "hil-sim"))
    if not os.path.exists(exe):
        pytest.fail(f"no hil-sim binary at {exe}: build it (cargo build --release -p hil-sim) or set HIL_SIM")

    def call(*args: str, cwd=None) -> str:
        p = subprocess.run([exe, *args], capture_output=True, text=True, cwd=cwd)
        assert p.returncode == 0, f"hil-sim {' '.join(args)} failed: {p.stderr}"
        return p.stdout

    return call
