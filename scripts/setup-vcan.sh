#!/usr/bin/env bash
# Bring up a SocketCAN virtual CAN interface (default vcan0) for the STEPFOC/MSG CAN tests and simulator.
#
#   sudo scripts/setup-vcan.sh            # vcan0
#   sudo scripts/setup-vcan.sh vcan1      # another name
#   scripts/setup-vcan.sh --down [NAME]   # remove it again
#
# Idempotent: running it again when the interface is already up changes nothing. Needs root (or sudo) to load
# the kernel module and create the link. Afterwards:
#   grippers sim msg --listen can://socketcan/vcan0?node=0
# The vcan module is not built into every kernel (containers, WSL and some cloud kernels lack it); the script
# says so instead of failing obscurely. Tests that need vcan skip themselves when it is absent;
# scripts/run-vcan-tests.sh runs them anyway (scripts/with-vcan boots a User-Mode Linux kernel that has vcan).
set -euo pipefail

down=0
if [[ "${1:-}" == "--down" ]]; then
    down=1
    shift
fi
if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
    sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'
    exit 0
fi
iface="${1:-vcan0}"
if [[ ! "$iface" =~ ^[A-Za-z0-9_.-]{1,15}$ ]]; then
    echo "setup-vcan: invalid interface name '$iface' (1-15 of A-Z a-z 0-9 _ . -)" >&2
    exit 2
fi

if [[ "$(uname -s)" != "Linux" ]]; then
    echo "setup-vcan: SocketCAN exists only on Linux; use python-can's 'virtual' or 'udp_multicast' bus instead." >&2
    exit 1
fi

if ! command -v ip >/dev/null 2>&1; then
    echo "setup-vcan: the 'ip' command (iproute2) is missing; install it (e.g. apt-get install iproute2)." >&2
    exit 1
fi

SUDO=()
if [[ "$(id -u)" -ne 0 ]]; then
    if command -v sudo >/dev/null 2>&1; then
        SUDO=(sudo)
    else
        echo "setup-vcan: needs root: run it as root or install sudo." >&2
        exit 1
    fi
fi

if [[ "$down" -eq 1 ]]; then
    if ip link show "$iface" >/dev/null 2>&1; then
        "${SUDO[@]}" ip link delete "$iface"
        echo "setup-vcan: $iface removed."
    else
        echo "setup-vcan: $iface does not exist; nothing to do."
    fi
    exit 0
fi

# 1. the kernel module (already loaded, built in, or loadable)
if [[ ! -d /sys/module/vcan ]]; then
    if ! "${SUDO[@]}" modprobe vcan 2>/dev/null; then
        cat >&2 <<MSG
setup-vcan: cannot load the 'vcan' kernel module.
  Kernel $(uname -r) either lacks it (CONFIG_CAN_VCAN is not set: common in containers, WSL2 and minimal cloud
  kernels) or the module files are not installed (try: apt-get install linux-modules-extra-\$(uname -r)).
  Inside a container the module must be loaded on the HOST (modprobe vcan) and the container needs
  CAP_NET_ADMIN (docker run --cap-add=NET_ADMIN ... or --network=host).
  Without vcan, use python-can's 'virtual' (in-process) or 'udp_multicast' (cross-process) buses:
    grippers sim msg --listen can://udp_multicast/239.74.163.2?node=0
MSG
        exit 1
    fi
fi

# 2. the link
if ip link show "$iface" >/dev/null 2>&1; then
    kind="$(ip -details link show "$iface" | awk '/vcan/ {print "vcan"; exit}')"
    if [[ "$kind" != "vcan" ]]; then
        echo "setup-vcan: $iface exists but is not a vcan interface; not touching it." >&2
        exit 1
    fi
else
    if ! "${SUDO[@]}" ip link add dev "$iface" type vcan; then
        echo "setup-vcan: 'ip link add dev $iface type vcan' failed (missing CAP_NET_ADMIN?)." >&2
        exit 1
    fi
fi

# 3. up (a vcan has no bitrate: 'ip link set ... type can bitrate' is for real controllers only)
if ! ip link show "$iface" | grep -q "state UP\|,UP"; then
    "${SUDO[@]}" ip link set up "$iface"
fi
echo "setup-vcan: $iface is up."
ip -brief link show "$iface" 2>/dev/null || ip link show "$iface"
