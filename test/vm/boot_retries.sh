#!/usr/bin/env bash
# Which failed VM boots boot.sh boots once more, and which stand: boot.sh runs
# against a stand-in for tools/vm/run.sh that plays each case's console and
# results, so no VM is needed.
#   boot_retries.sh            (exit 0 all cases behaved, 1 otherwise)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

mkdir -p "$work/test/vm" "$work/tools/vm" "$work/cache"
cp "$here/boot.sh" "$work/test/vm/boot.sh"
: > "$work/test/vm/guest.sh"
for f in stamp vmlinux initramfs.cpio; do echo stand-in > "$work/cache/$f"; done
# boot.sh skips where QEMU is missing; the stand-in never starts it.
mkdir -p "$work/bin"
printf '#!/bin/sh\necho "QEMU emulator version 0 (stand-in)"\n' > "$work/bin/qemu-system-x86_64"
chmod +x "$work/bin/qemu-system-x86_64"
export PATH=$work/bin:$PATH
# The stand-in: every check of the boot passes, unless STAND_IN_CASE makes
# attempt N of boot NAME fail as the case says. run.sh's arguments:
# --cache DIR GUEST OUT all out=OUT checks=A,B KEY=VALUE...
cat > "$work/tools/vm/run.sh" <<'STAND_IN'
#!/usr/bin/env bash
set -eu
out=$4
checks=$(printf '%s\n' "$@" | sed -n 's/^checks=//p')
first=${checks%%,*}
attempt=$(( $(cat "$out/.attempts-$first" 2>/dev/null || echo 0) + 1 ))
echo "$attempt" > "$out/.attempts-$first"
results() {  # every check of the boot passed
  for c in ${checks//,/ }; do
    echo 0 > "$out/$c.rc"
    echo "$c passed in attempt $attempt" > "$out/$c.log"
  done
}
fail() {  # fail CONSOLE_LINE: the VM gives no result
  echo "$1" > "$out/console.log"
  exit 125
}
lockup='[  656.71] watchdog: BUG: soft lockup - CPU#1 stuck for 22s! [systemctl:260]'
oops='[   12.30] BUG: kernel NULL pointer dereference, address: 0000000000000008'
case "${STAND_IN_CASE}:$first:$attempt" in
  # The check passed, then the kernel locked up (in the shutdown, say).
  lockup-once:watchdog:1 | lockup-twice:watchdog:1) results; fail "$lockup" ;;
  # Locked up before the check could say anything.
  lockup-twice:watchdog:2) fail "$lockup" ;;
  oops-in-main:can:1) fail "$oops" ;;
  oops-once-after-unplug:gpiod_lost:1) results; fail "$oops" ;;
  check-failed:watchdog:*)
    echo 1 > "$out/watchdog.rc"
    echo "check watchdog: rc=1" > "$out/console.log"
    exit 1 ;;
esac
results
for c in ${checks//,/ }; do echo "check $c: rc=0"; done > "$out/console.log"
STAND_IN
chmod +x "$work/tools/vm/run.sh"

failures=0
# expect CASE EXIT BOOTED_AGAIN KEPT_CONSOLE: boot.sh's exit status (0 or
# not), whether it said it boots once more, and the first console it keeps
# ("" for none).
expect() {
  local case=$1 want_exit=$2 want_again=$3 kept=$4 out=$work/out-$1 rc=0
  STAND_IN_CASE=$case bash "$work/test/vm/boot.sh" "$work/cache" "$out" > "$work/$case.log" 2>&1 || rc=$?
  local again=no
  grep -q 'booting it once more' "$work/$case.log" && again=yes
  if { [ "$want_exit" = 0 ] && [ "$rc" -ne 0 ]; } || { [ "$want_exit" != 0 ] && [ "$rc" -eq 0 ]; } ||
     [ "$again" != "$want_again" ] || { [ -n "$kept" ] && [ ! -f "$out/$kept" ]; }; then
    echo "FAILED: $case: exit $rc, booted again: $again, kept $kept: $([ -z "$kept" ] || [ -f "$out/$kept" ] && echo yes || echo no)"
    sed 's/^/  | /' "$work/$case.log"
    failures=$((failures + 1))
  else
    echo "ok: $case (exit $rc, booted again: $again${kept:+, first console kept as $kept})"
  fi
}

expect none 0 no ""
expect lockup-once 0 yes console-watchdog-lockup.log
expect lockup-twice 1 yes console-watchdog-lockup.log
expect oops-in-main 1 no ""
expect oops-once-after-unplug 0 yes console-gpiod_lost-oops.log
expect check-failed 1 no ""

# The boot that stood after a second lockup leaves no result for its check:
# the first boot's must not answer for it.
if [ -f "$work/out-lockup-twice/watchdog.rc" ]; then
  echo "FAILED: lockup-twice: a result for watchdog is left: $(cat "$work/out-lockup-twice/watchdog.log")"
  failures=$((failures + 1))
fi
# After one lockup, the check's result is the second boot's.
if ! grep -q 'attempt 2' "$work/out-lockup-once/watchdog.log"; then
  echo "FAILED: lockup-once: watchdog's result is not the second boot's: $(cat "$work/out-lockup-once/watchdog.log")"
  failures=$((failures + 1))
fi
[ "$failures" -eq 0 ] || exit 1
echo "boot.sh boots once more after one soft lockup in any boot and one oops in a chip-unplug boot; nothing else"
