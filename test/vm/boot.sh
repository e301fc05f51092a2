#!/usr/bin/env bash
# CTest fixture "vm": boots the test VM (four times) and runs every guest check
# (test/vm/guest.sh), leaving per-check results in OUTDIR for test/vm/check.sh.
#
#   boot.sh CACHE_DIR OUTDIR KEY=VALUE...   (KEYs as guest.sh takes them)
# Exit: 0 the VM ran the checks (their own outcomes are the per-check tests'),
# 77 the VM cannot run here (reason on stdout and in OUTDIR/skip), else failed.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
tools=$here/../../tools/vm
[ $# -ge 2 ] || { echo "usage: $0 CACHE_DIR OUTDIR KEY=VALUE..." >&2; exit 2; }
cache=$1 out=$2
shift 2

# Never let a previous run's results answer for this one.
rm -rf "$out"
mkdir -p "$out"

skip() {
  echo "SKIP: $*" | tee "$out/skip"
  exit 77
}
command -v qemu-system-x86_64 >/dev/null || skip "qemu-system-x86_64 is not installed (run tools/vm/prepare.sh $cache)"
qemu-system-x86_64 --version >/dev/null 2>&1 || skip "qemu-system-x86_64 does not run"
for f in stamp vmlinux initramfs.cpio; do
  [ -s "$cache/$f" ] ||
    skip "VM not prepared or preparation failed: no $f in $cache (run tools/vm/prepare.sh $cache)"
done

# Boots: checks that unplug a gpio-sim chip under a requested line go last in
# a boot of their own, because Debian 12's kernel may not survive a later GPIO
# request in the same boot (see check_gpiod_lost in guest.sh); the systemd
# watchdog check starts udevd and a journal, so it has its own too. Each boot's
# console is kept as console-NAME.log.
# The VM's own deadline stays under the CTest TIMEOUT so that a hang is
# reported by run.sh (exit 125 with the console), not killed silently. It is
# about five times what the checks take on an idle host: a loaded host slows
# the emulated guest down that much.
boots=(
  "main can,v4l2,gpio,libcamera,v4l2_source,socketcan,libcamera_source,gpiod,libcamera_reopen,paired_nir,daemon,toolsim 1200"
  "faults faults 600"
  "gpiod_lost gpiod_lost 300"
  "watchdog watchdog 900"
)
# A guest kernel that died (an oops, not a check's verdict) in a boot that
# unplugs a chip under a requested line is that known kernel fault, not
# stemd's: the boot runs once more, its first console kept as
# console-NAME-oops.log. A second oops, or any failure without one, stands.
oops='general protection fault|Oops: |BUG: |kernel BUG at'
failed=0
for b in "${boots[@]}"; do
  read -r name checks timeout_s <<< "$b"
  for attempt in 1 2; do
    rc=0
    STEMD_VM_TIMEOUT=${STEMD_VM_TIMEOUT:-$timeout_s} STEMD_VM_QUIET=1 \
      "$tools/run.sh" --cache "$cache" "$here/guest.sh" "$out" all "out=$out" "checks=$checks" "$@" || rc=$?
    mv "$out/console.log" "$out/console-$name.log" 2>/dev/null || true
    case $name in faults | gpiod_lost) ;; *) break ;; esac
    [ "$attempt" = 1 ] && grep -qE "$oops" "$out/console-$name.log" 2>/dev/null || break
    echo "VM boot '$name': the guest kernel died ($(grep -m1 -oE "($oops).{0,60}" "$out/console-$name.log")); booting it once more"
    mv "$out/console-$name.log" "$out/console-$name-oops.log"
  done
  if [ "$rc" -ne 0 ]; then
    echo "VM boot '$name' failed (run.sh exit $rc; 125 = the VM gave no result). Console:"
    tail -n 40 "$out/console-$name.log" 2>/dev/null || true
    failed=1
  fi
  grep '^check ' "$out/console-$name.log" || true
done
exit "$failed"
