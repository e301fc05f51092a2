#!/usr/bin/env bash
# Soak (a measurement, not a test): stemd replays a synthetic strip in a loop
# at its recorded 30 fps (preloaded), with actuation, the plant map and the CAN log on,
# for a given time. Its resident memory (VmRSS) is sampled at a fixed
# interval; the script prints the machine, the first and last sample, the
# minimum and maximum after a warm-up (default 60 s) and the least-squares
# slope over those samples, in KiB per hour.
# A flat memory has a slope near zero; a leak of one small allocation per
# frame (30 frames/s) would show as hundreds of KiB per hour.
#   tools/soak.sh [--minutes M] [--sample-s S] [--warmup-s W] [--length-mm L] [--out DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
minutes=60 sample_s=10 warmup_s=60 length_mm=3000 out=
while [ $# -gt 0 ]; do
  case $1 in
    --minutes) minutes=$2; shift 2 ;;
    --sample-s) sample_s=$2; shift 2 ;;
    --warmup-s) warmup_s=$2; shift 2 ;;
    --length-mm) length_mm=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    *) echo "usage: $0 [--minutes M] [--sample-s S] [--warmup-s W] [--length-mm L] [--out DIR]" >&2; exit 2 ;;
  esac
done
build=build/release
[ -x $build/src/runtime/stemd ] || { cmake -S . -B $build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null && cmake --build $build; }

strip=$build/soak-strip-$length_mm
if [ ! -f "$strip/frames.csv" ]; then
  echo "soak: generating a ${length_mm} mm strip in $strip (once)"
  $build/tools/stemd-synth --strip --out "$strip" --length-mm "$length_mm" --seed 23 >/dev/null
fi
[ -n "$out" ] || out=$(mktemp -d)
mkdir -p "$out"
echo "machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(uname -r), $(date -u +%FT%TZ)"
echo "strip: $(($(wc -l < "$strip/frames.csv") - 1)) frames, looped at 30 fps for $minutes min; RSS every $sample_s s -> $out/rss.csv"

$build/src/runtime/stemd --replay "$strip" --set scheduler.policy=all --set source.replay_preload=true \
  --can-log "$out/can.log" --map "$out/map.jsonl" 2>"$out/err" &
pid=$!
trap 'kill "$pid" 2>/dev/null || true' EXIT
echo "t_s,rss_kib" > "$out/rss.csv"
start=$(date +%s)
end=$((start + minutes * 60))
while kill -0 "$pid" 2>/dev/null && [ "$(date +%s)" -lt "$end" ]; do
  sleep "$sample_s"
  rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
  [ -n "$rss" ] && echo "$(($(date +%s) - start)),$rss" >> "$out/rss.csv"
done
kill -0 "$pid" 2>/dev/null || { echo "soak: stemd ended early:"; tail -5 "$out/err"; exit 1; }
kill -TERM "$pid"
wait "$pid" || { echo "soak: stemd exited with $?"; tail -5 "$out/err"; exit 1; }
trap - EXIT

grep "total:" "$out/err" | tail -1 | sed 's/.*total: /stemd: /'
echo "CAN log lines: $(wc -l < "$out/can.log"), plant map lines: $(wc -l < "$out/map.jsonl")"
# Slope over the samples after the warm-up (start-up: preloading the strip,
# first allocations of the tracker and the writers).
awk -F, -v warmup_s="$warmup_s" '
  BEGIN { n = 0 }
  NR > 1 { t[n] = $1; r[n] = $2; n++ }
  END {
    first = 0
    while (first < n && t[first] < warmup_s) first++
    if (n - first < 3) { print "soak: too few samples after the warm-up"; exit 1 }
    m = 0; st = sr = stt = str = 0
    lo = hi = r[first]
    for (i = first; i < n; i++) {
      st += t[i]; sr += r[i]; stt += t[i] * t[i]; str += t[i] * r[i]; m++
      if (r[i] < lo) lo = r[i]; if (r[i] > hi) hi = r[i]
    }
    slope_kib_per_s = (m * str - st * sr) / (m * stt - st * st)
    printf "RSS: first %d KiB, last %d KiB; after warm-up (%d samples) min %d, max %d KiB; slope %.1f KiB/h\n",
           r[0], r[n - 1], m, lo, hi, slope_kib_per_s * 3600
  }' "$out/rss.csv"
