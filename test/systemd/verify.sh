#!/usr/bin/env bash
# The installed unit passes systemd-analyze verify, and installing puts the
# binaries, configuration and unit where the unit expects them.
#   verify.sh BUILD_DIR
set -euo pipefail
build=$1
command -v systemd-analyze >/dev/null || { echo "SKIP: systemd-analyze is not installed (package systemd)"; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
unit="$tmp/prefix/lib/systemd/system/stemd.service"
for f in bin/stemd bin/stemd-detect etc/stemd/stemd.yaml etc/stemd/stemd.dbc lib/sysusers.d/stemd.conf \
    share/stemd/systemd/stemd-web.conf; do
  [ -e "$tmp/prefix/$f" ] || { echo "FAIL: not installed: $f"; exit 1; }
done
grep -q "^ExecStart=$tmp/prefix/bin/stemd --config $tmp/prefix/etc/stemd/stemd.yaml$" "$unit" \
  || { echo "FAIL: ExecStart does not point at the install: $(grep ExecStart "$unit")"; exit 1; }
# The installed config is valid for the installed binary.
"$tmp/prefix/bin/stemd" --config "$tmp/prefix/etc/stemd/stemd.yaml" --check-config >/dev/null
# verify exits 0 even for unknown keys and unparsable values: it reports
# them as "<unit file>:<line>: ...". Any such line is a failure; messages
# about the machine (no running systemd) do not name the unit file.
out=$(systemd-analyze verify --man=no "$unit" 2>&1) || { echo "FAIL: $out"; exit 1; }
if grep -F "$unit:" <<<"$out"; then
  echo "FAIL: systemd-analyze verify complains about the unit (above)"
  exit 1
fi
# TCP/IP is denied unless the live view's drop-in is installed, and the
# drop-in is not installed where it would apply by itself.
families=$(grep '^RestrictAddressFamilies=' "$unit")
grep -q 'AF_INET' <<<"$families" && { echo "FAIL: the unit allows TCP/IP: $families"; exit 1; }
[ ! -e "$tmp/prefix/lib/systemd/system/stemd.service.d" ] || { echo "FAIL: a drop-in directory is installed"; exit 1; }
# With the drop-in beside the unit (as /etc/systemd/system/stemd.service.d/
# would hold it), verify still has nothing to say, and the drop-in adds the
# families.
mkdir -p "$tmp/withweb/stemd.service.d"
cp "$unit" "$tmp/withweb/stemd.service"
cp "$tmp/prefix/share/stemd/systemd/stemd-web.conf" "$tmp/withweb/stemd.service.d/web.conf"
out=$(systemd-analyze verify --man=no "$tmp/withweb/stemd.service" 2>&1) || { echo "FAIL: with the drop-in: $out"; exit 1; }
if grep -F -e "$tmp/withweb/" <<<"$out"; then
  echo "FAIL: systemd-analyze verify complains about the unit or its drop-in (above)"
  exit 1
fi
grep -qx 'RestrictAddressFamilies=AF_INET AF_INET6' "$tmp/withweb/stemd.service.d/web.conf" \
  || { echo "FAIL: the drop-in does not allow AF_INET/AF_INET6"; exit 1; }
echo "systemd verify: ok"
