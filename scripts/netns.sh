#!/usr/bin/env bash
# Run a command inside a private, loopback-only network namespace with a private /dev/shm.
#
# Usage: bash scripts/netns.sh CMD [ARGS...]
#
# Every process that starts rclpy (tests, demo, nodes) must run this way: DDS discovery then cannot
# leave the machine nor meet other runs (Fast DDS shared memory lives in the private /dev/shm).
# It needs root or CAP_SYS_ADMIN (unshare --net --mount).
#
# Opt-out for real deployments, where the nodes must talk to a real robot or other hosts:
#   GEODESIC_PLANNER_NETNS=off bash scripts/netns.sh CMD ...
# runs CMD directly (with a warning); ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST is still set.
set -euo pipefail

if [ "$#" -eq 0 ]; then
    echo "usage: $0 CMD [ARGS...]" >&2
    exit 2
fi

export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST

case "${GEODESIC_PLANNER_NETNS:-on}" in
    off|OFF|0|false|no)
        echo "netns: WARNING: GEODESIC_PLANNER_NETNS=off: running without network isolation" \
             "(ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST only; DDS still binds every interface)" >&2
        exec "$@"
        ;;
esac

# Probe first so that a refusal gives one clear message instead of unshare's own.
if ! probe_err="$(unshare --net --mount sh -c : 2>&1)"; then
    echo "netns: ERROR: cannot create a private network namespace (unshare --net --mount: ${probe_err:-failed});" \
         "this needs root or CAP_SYS_ADMIN. To run without isolation (e.g. on a real robot)," \
         "set GEODESIC_PLANNER_NETNS=off." >&2
    exit 2
fi

exec unshare --net --mount sh -c '
    fail() { echo "netns: ERROR: $1" >&2; exit 2; }
    if command -v ip >/dev/null 2>&1; then
        ip link set lo up || fail "ip link set lo up failed"
    else  # no iproute2: bring lo up with the SIOCGIFFLAGS/SIOCSIFFLAGS ioctls
        python3 -c "import fcntl, socket, struct
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
flags = struct.unpack(\"16sh22x\", fcntl.ioctl(s, 0x8913, struct.pack(\"16sh22x\", b\"lo\", 0)))[1]
fcntl.ioctl(s, 0x8914, struct.pack(\"16sh22x\", b\"lo\", flags | 1))" ||
            fail "could not bring up lo (no ip command; python3 ioctl fallback failed): install iproute2"
    fi
    mount -t tmpfs tmpfs /dev/shm || fail "mount -t tmpfs tmpfs /dev/shm failed"
    mount -t sysfs sysfs /sys 2>/dev/null || true  # so /sys/class/net lists this namespace (lo)
    export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
    export GEODESIC_PLANNER_IN_NETNS=1
    exec "$@"' netns-sh "$@"
