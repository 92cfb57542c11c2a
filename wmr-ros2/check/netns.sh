# Sourced by the check scripts that start DDS participants (wmr-ros2/check/
# run.sh, run-fastdds.sh, ros-mcap/check/live.sh): a private network
# namespace with only its loopback, up, multicast routed to it, so DDS
# discovery (and any server a check starts) never leaves the machine.
# Needs scripts/check-lib.sh sourced first (fail).

# The namespace's setup, run inside it as root of the namespace.
NETNS_SETUP="ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo"

# netns_tools: fails unless unshare and ip are installed (installs iproute2
# with apt-get when ip is missing and apt-get is there).
netns_tools() {
    command -v unshare >/dev/null || fail "unshare (util-linux) not found"
    if ! command -v ip >/dev/null; then
        { command -v apt-get >/dev/null && apt-get update -qq &&
            DEBIAN_FRONTEND=noninteractive apt-get install -y -qq iproute2; } ||
            fail "ip not found (apt-get install iproute2: the namespace's loopback needs it)"
    fi
}

# in_netns COMMAND...: runs COMMAND (a bash command line, with the
# environment exported by the caller) in a new private network namespace,
# WMR_ROS2_IN_NETNS=1 set inside; its exit status.
in_netns() {
    unshare -n bash -c "$NETNS_SETUP && WMR_ROS2_IN_NETNS=1 $*"
}

# check_netns: inside the namespace, fails when it has any interface but lo.
check_netns() {
    if ip -o link show | grep -v ' lo:' | grep -q .; then
        fail "the namespace has an interface other than lo"
    fi
}
