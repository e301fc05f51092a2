#!/usr/bin/env bash
# Load benchmark (a measurement, not a test): stemd replays a 10 m synthetic
# strip (preloaded, at its recorded 30 fps, odometer from the recording) with
# real-time settings (SCHED_FIFO threads, mlockall) while stress-ng keeps
# every core busy. Prints the machine, then drops, deadline misses and the
# capture -> TARGET latency (p50, p99, max) from stemd's final status line.
#   tools/bench-load.sh [--hogs N] [--length-mm L] [--no-stress]
# Needs root (or CAP_SYS_NICE and a memlock limit) for the real-time settings.
set -euo pipefail
cd "$(dirname "$0")/.."
hogs=8 length_mm=10000 stress=1
while [ $# -gt 0 ]; do
  case $1 in
    --hogs) hogs=$2; shift 2 ;;
    --length-mm) length_mm=$2; shift 2 ;;
    --no-stress) stress=0; shift ;;
    *) echo "usage: $0 [--hogs N] [--length-mm L] [--no-stress]" >&2; exit 2 ;;
  esac
done
build=build/release
if [ "$stress" = 1 ] && ! command -v stress-ng >/dev/null; then
  sudo=(); [ "$(id -u)" -eq 0 ] || sudo=(sudo)
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends stress-ng
fi
[ -x $build/src/runtime/stemd ] || { cmake -S . -B $build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null && cmake --build $build; }

strip=$build/bench-load-strip-$length_mm
if [ ! -f "$strip/frames.csv" ]; then
  echo "bench-load: generating a ${length_mm} mm strip in $strip (once)"
  $build/tools/stemd-synth --strip --out "$strip" --length-mm "$length_mm" --seed 11 >/dev/null
fi
out=$(mktemp -d)
hog_pid=
trap '[ -z "$hog_pid" ] || kill "$hog_pid" 2>/dev/null || true; rm -rf "$out"' EXIT

echo "machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(uname -r), $(date -u +%F)"
echo "strip: $(($(wc -l < "$strip/frames.csv") - 1)) frames of 1296x966 at 30 fps; load: $([ "$stress" = 1 ] && echo "stress-ng --cpu $hogs" || echo none)"
if [ "$stress" = 1 ]; then
  stress-ng --cpu "$hogs" --timeout 0 --quiet &
  hog_pid=$!
  sleep 1
fi
$build/src/runtime/stemd --replay "$strip" --once \
  --set source.replay_preload=true --set threads.mlockall=true \
  --set threads.capture_priority=80 --set threads.processing_priority=70 --set threads.actuator_priority=90 \
  --can-log "$out/can.log" --map "$out/map.jsonl" 2>"$out/err" || { tail -5 "$out/err"; exit 1; }
grep -E " (warning|error) " "$out/err" | grep -v "no CAN interface\|no GPIO enable" || true
total=$(grep "total:" "$out/err" | tail -1 | sed 's/.*total: //')
echo "stemd: $total"
