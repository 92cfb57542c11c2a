# Sourced by ros-mcap/check/run.sh and wmr-ros2/check/run.sh (each sources
# scripts/check-lib.sh and cds to the repository's root first).

# The independent Python readers, exact versions, in one venv for both
# checks: cyclonedds (the ROS 2 interop), mcap and rosbags (both).
CYCLONEDDS_VERSION=11.0.1
MCAP_VERSION=1.6.0
ROSBAGS_VERSION=0.11.9

# check_venv DIR: DIR becomes a venv with exactly these versions (made anew
# when any differs); sets PY.
check_venv() {
    local venv=$1 want="$CYCLONEDDS_VERSION $MCAP_VERSION $ROSBAGS_VERSION"
    if ! "$venv/bin/python" -c "import cyclonedds, mcap, rosbags" 2>/dev/null ||
        [ "$("$venv/bin/python" -c 'import importlib.metadata as m; print(m.version("cyclonedds"), m.version("mcap"), m.version("rosbags"))')" != "$want" ]; then
        python3 -m venv "$venv" || fail "python3 -m venv (apt-get install python3-venv)"
        "$venv/bin/pip" install --quiet "cyclonedds==$CYCLONEDDS_VERSION" "mcap==$MCAP_VERSION" "rosbags==$ROSBAGS_VERSION" ||
            fail "pip install cyclonedds==$CYCLONEDDS_VERSION mcap==$MCAP_VERSION rosbags==$ROSBAGS_VERSION"
    fi
    PY="$venv/bin/python"
    echo "python: $("$PY" --version), cyclonedds $CYCLONEDDS_VERSION, mcap $MCAP_VERSION, rosbags $ROSBAGS_VERSION"
}

# build_host_tools: target/release/hil-sim and wmr as the README's test
# command builds them. `cargo test --release --workspace` resolves the
# features with the workspace's dev-dependencies (controller-core's
# test-doubles, ...); `cargo build -p hil-sim -p wmr` resolves others and
# compiled controller-core, wmr-device, robot-app, sim-robot, hil-sim and wmr
# a second time (175 CPU-s, D124). After the test command nothing compiles.
build_host_tools() {
    cargo test --release --workspace --no-run --quiet
}
