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
  "main can,v4l2,gpio,libcamera,v4l2_source,socketcan,libcamera_source,gpiod,libcamera_reopen,paired_nir,daemon,toolsim,record_odometry,record_encoder,tool_status 1200"
  "faults faults 600"
  "gpiod_lost gpiod_lost 300"
  "watchdog watchdog 900"
)
# A guest kernel that died (an oops, not a check's verdict) in a boot that
# unplugs a chip under a requested line is that known kernel fault, not
# stemd's: the boot runs once more, its first console kept as
# console-NAME-oops.log. A second oops, or any failure without one, stands.
# So does a soft lockup in any boot (the emulated guest's CPUs stuck in its
# own kernel, which then panics: tools/vm/run.sh), kept as
# console-NAME-lockup.log. Seen once in CI, on 2026-12-06: both vCPUs of the
# watchdog boot spun in the kernel for ten minutes under TCG, in systemd and
# systemctl, with vm.boot running alone. A second lockup stands. Before a second
# boot, the first one's per-check results go, so that none can answer for it.
oops='general protection fault|Oops: |BUG: |kernel BUG at'
lockup='BUG: soft lockup'
forget_results() {
  local c
  for c in ${1//,/ }; do rm -f "$out/$c.rc" "$out/$c.log"; done
}
failed=0
for b in "${boots[@]}"; do
  read -r name checks timeout_s <<< "$b"
  for attempt in 1 2; do
    rc=0
    STEMD_VM_TIMEOUT=${STEMD_VM_TIMEOUT:-$timeout_s} STEMD_VM_QUIET=1 \
      "$tools/run.sh" --cache "$cache" "$here/guest.sh" "$out" all "out=$out" "checks=$checks" "$@" || rc=$?
    console=$out/console-$name.log
    mv "$out/console.log" "$console" 2>/dev/null || true
    [ "$attempt" = 1 ] || break
    if [ "$rc" -ne 0 ] && grep -qE "$lockup" "$console" 2>/dev/null; then
      echo "VM boot '$name': the guest kernel locked up ($(grep -m1 -oE "$lockup.{0,40}" "$console")); booting it once more"
      mv "$console" "$out/console-$name-lockup.log"
      forget_results "$checks"
      continue
    fi
    case $name in faults | gpiod_lost) ;; *) break ;; esac
    grep -qE "$oops" "$console" 2>/dev/null || break
    echo "VM boot '$name': the guest kernel died ($(grep -m1 -oE "($oops).{0,60}" "$console")); booting it once more"
    mv "$console" "$out/console-$name-oops.log"
    forget_results "$checks"
  done
  if [ "$rc" -ne 0 ]; then
    echo "VM boot '$name' failed (run.sh exit $rc; 125 = the VM gave no result). Console:"
    tail -n 40 "$out/console-$name.log" 2>/dev/null || true
    failed=1
  fi
  grep '^check ' "$out/console-$name.log" || true
done
exit "$failed"
