#!/usr/bin/env bash
# SIGTERM while the gpsd host's name is being looked up and the DNS server
# never answers. getaddrinfo cannot be cut short: it waits out the
# resolver's timeout (30 s here), so stemd must stop without waiting for it.
# Runs in a private mount and network namespace (needs root): only lo, and
# /etc/resolv.conf naming 127.0.0.1, where a UDP socket takes the queries
# and never replies. Fails if stemd is still alive 5 s after the signal.
#   gpsd_dns.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1
tools=$2
src=$3
if [ "${STEMD_TEST_IN_NAMESPACE:-}" != 1 ]; then
  [ "$(id -u)" -eq 0 ] && unshare --mount --net true 2>/dev/null ||
    { echo "SKIP: needs root for a private mount and network namespace (unshare --mount --net)"; exit 77; }
  command -v python3 >/dev/null || { echo "SKIP: python3 (the silent DNS server) is not installed"; exit 77; }
  PATH=$PATH:/usr/sbin:/sbin command -v ip >/dev/null || { echo "SKIP: ip (iproute2) is not installed"; exit 77; }
  exec env STEMD_TEST_IN_NAMESPACE=1 unshare --mount --net bash "$0" "$@"
fi
source "$src/test/support/script.sh"
kBoundMs=5000

PATH=$PATH:/usr/sbin:/sbin ip link set lo up
# The resolver's files, seen only in this namespace: names from /etc/hosts
# and DNS (no mDNS or systemd-resolved module that could answer otherwise).
# Without a resolv.conf glibc asks 127.0.0.1 anyway; RES_OPTIONS applies
# either way.
export RES_OPTIONS="timeout:30 attempts:1"
printf 'nameserver 127.0.0.1\n' >"$tmp/resolv.conf"
printf 'hosts: files dns\n' >"$tmp/nsswitch.conf"
[ ! -e /etc/resolv.conf ] || mount --bind "$tmp/resolv.conf" /etc/resolv.conf
[ ! -e /etc/nsswitch.conf ] || mount --bind "$tmp/nsswitch.conf" /etc/nsswitch.conf

python3 - "$tmp/asked" <<'PY' &
import socket, sys
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 53))
open(sys.argv[1] + ".ready", "w").close()
while True:
    s.recvfrom(4096)   # a query: never answered
    open(sys.argv[1], "w").close()
PY
pid=$!
for _ in $(seq 100); do [ -e "$tmp/asked.ready" ] && break; sleep 0.1; done
[ -e "$tmp/asked.ready" ] || fail "the silent DNS server did not start"

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 3 >/dev/null
"$stemd" --replay "$tmp/rec" --can-log /dev/null --set gnss.source=gpsd --set gnss.host=gpsd.stemd-test.example \
  --set log.level=debug 2>"$tmp/err" &
stemd_pid=$!
pid="$pid $stemd_pid"
for _ in $(seq 300); do
  [ -e "$tmp/asked" ] && break
  kill -0 "$stemd_pid" 2>/dev/null || fail "stemd exited early: $(tail -3 "$tmp/err")"
  sleep 0.1
done
[ -e "$tmp/asked" ] || fail "no DNS query for the gpsd host within 30 s: $(tail -3 "$tmp/err")"

t0=$(date +%s%N)
kill -TERM "$stemd_pid"
while kill -0 "$stemd_pid" 2>/dev/null; do
  [ $((($(date +%s%N) - t0) / 1000000)) -lt $kBoundMs ] ||
    fail "stemd still running $kBoundMs ms after SIGTERM, its gpsd host's name unanswered"
  sleep 0.01
done
ms=$((($(date +%s%N) - t0) / 1000000))
rc=0
wait "$stemd_pid" || rc=$?
[ $rc -eq 0 ] || fail "SIGTERM during the name lookup: exit $rc: $(tail -3 "$tmp/err")"
# The lookup starts while stemd is still starting (the replay's preload may
# not be done): the signal can land in either phase, each with its message.
grep -qE "SIGTERM( while starting)?: stopping" "$tmp/err" || fail "no stop message: $(tail -3 "$tmp/err")"
grep -q "gpsd gpsd.stemd-test.example:[0-9]*: .* 0 connections" "$tmp/err" ||
  fail "gpsd connected?: $(grep gpsd "$tmp/err")"
echo "gpsd host name unanswered by DNS: exit 0 after $ms ms"
