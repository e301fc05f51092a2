# Shared by the live view's tests, sourced with the script's arguments
# (STEMD TOOLS_DIR SOURCE_DIR): sets $stemd, $tools, $src, a scratch $tmp
# removed on exit (with the stemd started here stopped) and fail MESSAGE.
set -euo pipefail
stemd=$1
tools=$2
src=$3
tmp=$(mktemp -d)
stemd_pid=""
trap '[ -z "$stemd_pid" ] || kill "$stemd_pid" 2>/dev/null || true; rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
. "$(dirname "${BASH_SOURCE[0]}")/../support/recording.sh"

# stop_stemd: the stemd start_stemd started, stopped and waited for.
stop_stemd() {
  [ -z "$stemd_pid" ] || { kill "$stemd_pid" && wait "$stemd_pid" 2>/dev/null || true; }
  stemd_pid=""
}

# Start stemd with the view on a free port (web.listen port 0: the kernel
# picks one, the log names it) and wait for it.
#   start_stemd LOG [stemd args...]   sets $stemd_pid and $base (http://127.0.0.1:PORT)
start_stemd() {
  local log=$1
  shift
  "$stemd" "$@" 2>"$log" &
  stemd_pid=$!
  base=""
  # Generous: a loaded 2-core machine may take a while to preload and start.
  for _ in $(seq 600); do
    base=$(grep -o 'web view at http://127.0.0.1:[0-9]*' "$log" | head -1 | sed 's/^web view at //') || true
    [ -n "$base" ] && break
    kill -0 "$stemd_pid" 2>/dev/null || fail "stemd exited before serving: $(cat "$log")"
    sleep 0.1
  done
  [ -n "$base" ] || fail "no 'web view at' line in 60 s: $(cat "$log")"
}

# GET PATH into FILE with python3 (no curl on a minimal machine); retries
# while the daemon is still starting.
fetch() {
  /usr/bin/python3 - "$base$1" "$2" <<'PY'
import sys, time, urllib.request
for attempt in range(100):
    try:
        with urllib.request.urlopen(sys.argv[1], timeout=30) as r, open(sys.argv[2], "wb") as out:
            out.write(r.read())
        sys.exit(0)
    except Exception as e:
        err = e
        time.sleep(0.2)
print("fetch %s: %s" % (sys.argv[1], err), file=sys.stderr)
sys.exit(1)
PY
}
