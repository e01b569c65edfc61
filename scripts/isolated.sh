#!/bin/sh
# isolated.sh CMD...: runs CMD in a network namespace of its own, with its own loopback (lo up, IPv4 and IPv6
# multicast routed on it). Two test suites run this way at once never collide on the fixed ports the README
# prints (127.0.0.1:1000, 2000, 3000) or on python-can's udp_multicast port and groups, which are host-wide
# (docs/protocols.md §2). CI uses it to run the Python 3.11 and 3.13 suites side by side (.ci/run).
#
# Needs root, or a kernel that lets an ordinary user create namespaces (then `unshare -r` maps the user to root
# inside: CMD then runs as root there, which binds port 1000 as the README's session does under sudo).
# Exit status: CMD's, or unshare's when no namespace can be made (a message says why).
set -eu
[ $# -gt 0 ] || { echo "usage: isolated.sh CMD [ARG]..." >&2; exit 2; }
if [ "$(id -u)" -eq 0 ]; then
    user=""
else
    user="-r"
fi
setup='ip link set lo up && ip route add 224.0.0.0/4 dev lo &&
    { ip -6 route add multicast ff00::/8 dev lo table local 2>/dev/null || true; } && exec "$@"'
# shellcheck disable=SC2086 # $user is empty or one flag
exec unshare $user -n sh -c "$setup" isolated.sh "$@"
