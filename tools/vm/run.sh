#!/usr/bin/env bash
# Boots stemd's test VM (see tools/vm/prepare.sh), runs a guest script in it
# and exits with the script's exit status.
#
#   tools/vm/run.sh [--cache DIR] GUEST_SCRIPT OUTDIR [ARG...]
#   tools/vm/run.sh [--cache DIR] --shell        interactive (Ctrl-A x quits)
#
# GUEST_SCRIPT is a host path, run by busybox sh in the guest with ARGs; see
# tools/vm/init for what it can use. OUTDIR is shared writable over 9p (same
# path in the guest's `hostrun`), how results come back. The console goes to
# OUTDIR/console.log and to stderr.
# Exit status: the guest script's; 125 = the VM gave no result (did not boot,
# crashed, timed out); 2 = usage.
# Environment: STEMD_VM_CACHE (default build/release/vm-cache),
#   STEMD_VM_TIMEOUT seconds for the whole VM run (default 300),
#   STEMD_VM_QUIET=1 keeps the console off stderr.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
cache=${STEMD_VM_CACHE:-$here/../../build/release/vm-cache}
log() { printf 'vm-run: %s\n' "$*" >&2; }
usage() { echo "usage: $0 [--cache DIR] GUEST_SCRIPT OUTDIR [ARG...] | [--cache DIR] --shell" >&2; exit 2; }

shell=0
while [ $# -gt 0 ]; do
  case $1 in
    --cache) [ $# -ge 2 ] || usage; cache=$2; shift 2 ;;
    --shell) shell=1; shift ;;
    *) break ;;
  esac
done
[ "$shell" = 1 ] || [ $# -ge 2 ] || usage

for f in vmlinux initramfs.cpio stamp; do
  [ -s "$cache/$f" ] || { log "no $cache/$f: run tools/vm/prepare.sh $cache"; exit 125; }
done
command -v qemu-system-x86_64 >/dev/null || { log "qemu-system-x86_64 not installed"; exit 125; }

# TCG, not KVM: CI machines have no usable KVM. -cpu max gives the guest the
# instructions Debian's kernel and the host's binaries may use; 2 vCPUs because
# TCG runs one host thread per vCPU (MTTCG). The host root goes in read-only.
# shellcheck disable=SC2054  # the commas are QEMU option syntax
qemu=(qemu-system-x86_64 -accel tcg -M pc -cpu max -smp 2 -m 1024
      -nodefaults -nographic -serial stdio -no-reboot
      -kernel "$cache/vmlinux" -initrd "$cache/initramfs.cpio"
      -virtfs local,path=/,mount_tag=host,security_model=none,readonly=on,multidevs=remap)
# A CPU stuck in the kernel for 20 s panics the guest, which then exits at
# once (panic=-1 with -no-reboot): the boot fails in seconds, not at the
# deadline, and panic_print=0x20 replays the whole kernel log to the console,
# where quiet had hidden the stuck CPU's stack.
cmdline="console=ttyS0 quiet panic=-1 softlockup_panic=1 panic_print=0x20"

if [ "$shell" = 1 ]; then
  exec "${qemu[@]}" -append "$cmdline stemd.shell"
fi

script=$(readlink -f "$1")
[ -f "$script" ] || { log "no guest script $1"; exit 2; }
mkdir -p "$2"
out=$(cd "$2" && pwd)
shift 2
case "$script$out" in *' '*) log "paths with spaces cannot go on the kernel command line"; exit 2 ;; esac
rm -rf "$out/.vm"
mkdir -p "$out/.vm"
# Arguments travel through the share: the kernel command line cannot quote.
[ $# -eq 0 ] || printf '%s\n' "$@" > "$out/.vm/args"

timeout_s=${STEMD_VM_TIMEOUT:-300}
console=$out/console.log
log "booting $(cut -d' ' -f1 "$cache/stamp") for $script (timeout ${timeout_s}s)"
start=$SECONDS
# -k: QEMU gets SIGTERM at the deadline and SIGKILL 5 s later if it ignores it.
# stdin from /dev/null: QEMU must not take over a terminal or wait for input.
set +e
timeout -k 5 "$timeout_s" "${qemu[@]}" \
    -virtfs "local,path=$out,mount_tag=out,security_model=none,multidevs=remap" \
    -append "$cmdline stemd.run=$script stemd.out=$out" < /dev/null 2>&1 |
  sed -u 's/\r//g; s/\x1bc//g; s/\x1b\[[0-9;?]*[A-Za-z]//g' |  # CRs, SeaBIOS's terminal resets
  if [ "${STEMD_VM_QUIET:-0}" = 1 ]; then cat > "$console"; else tee "$console" >&2; fi
qemu_status=${PIPESTATUS[0]}
set -e
[ "$qemu_status" != 124 ] || log "VM timed out after ${timeout_s}s"

# The guest writes its status to the share and the console; the share is what
# counts (the console line is a fallback when the share did not mount).
rc=$(cat "$out/.vm/rc" 2>/dev/null ||
     sed -n 's/^STEMD-VM-RESULT rc=\([0-9]*\).*/\1/p' "$console" | tail -n1)
log "wall $((SECONDS - start)) s, guest rc=${rc:-none} (qemu status $qemu_status)"
[ -n "$rc" ] || { sed -n 's/^STEMD-VM-ERROR /vm-run: guest: /p' "$console" >&2; exit 125; }
exit "$rc"
