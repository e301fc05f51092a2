#!/usr/bin/env bash
# Live view benchmark (a measurement, not a test): stemd replays a preloaded
# late-stage recording (1296x966, paced at its recorded 30 fps) with the
# view on, once without a client and once with one polling /frame.jpg at
# 10 fps (and the counters and plants every second, as the page does);
# rounds interleaved. Prints the machine, then per run the capture->result
# latency p50/p99 and the drops from stemd's final status line, and the
# medians and ranges of both modes, and the processing thread's cycle
# (mean, and the metrics bucket its p99 falls in), which holds the live
# view's hand-over. Target: p99 grows by <= 0.5 ms, no drops. --build DIR:
# another build's stemd (an older commit's, to compare).
#   tools/bench-web.sh [--rounds N] [--frames N] [--build DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=5 frames=300 build=build/release
while [ $# -gt 0 ]; do
  case $1 in
    --rounds) rounds=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    *) echo "usage: $0 [--rounds N] [--frames N] [--build DIR]" >&2; exit 2 ;;
  esac
done
[ -x $build/src/runtime/stemd ] || { cmake -S . -B $build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null && cmake --build $build; }
# One recording for every build compared.
rec=build/bench-web-rec-$frames
synth=build/release/tools/stemd-synth
[ -x $synth ] || synth=$build/tools/stemd-synth
if [ ! -f "$rec/frames.csv" ]; then
  echo "bench-web: generating $frames late-stage frames in $rec (once)"
  $synth --out "$rec" --preset late --frames "$frames" --fps 30 >/dev/null
fi
out=$(mktemp -d)
client_pid=
trap '[ -z "$client_pid" ] || kill "$client_pid" 2>/dev/null || true; rm -rf "$out"' EXIT

echo "machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(uname -r), load $(cut -d' ' -f1-3 /proc/loadavg), $(date -u +%F)"
echo "recording: $frames frames of 1296x966 at 30 fps, preloaded, paced; web.fps 5 (default), web.max_width_px 640"

run() {  # MODE ROUND
  local mode=$1 round=$2 log="$out/$1-$2.err"
  $build/src/runtime/stemd --replay "$rec" --once --can-log /dev/null \
    --set source.replay_preload=true --set web.listen=127.0.0.1:0 2>"$log" &
  local pid=$!
  # The view starts once the recording is preloaded (seconds on a loaded machine).
  local base=""
  while [ -z "$base" ] && kill -0 "$pid" 2>/dev/null; do
    base=$(grep -o 'http://127.0.0.1:[0-9]*' "$log" | head -1) || true
    sleep 0.05
  done
  [ -n "$base" ] || { tail -3 "$log"; exit 1; }
  # Both modes read /metrics every second (the processing thread's cycle
  # histogram, whole run; it makes no frame due); the client also polls
  # /frame.jpg at 10 fps and the counters and plants every second.
  /usr/bin/python3 - "$base" "$out/$mode-$round" "$mode" <<'PY' &
import sys, time, urllib.request
base, prefix, mode = sys.argv[1], sys.argv[2], sys.argv[3]
jpegs, next_t, i = 0, time.monotonic(), 0
try:
    while True:
        if mode == "client":
            with urllib.request.urlopen(base + "/frame.jpg", timeout=5) as r:
                jpegs += len(r.read()) > 0
        if i % 10 == 0:
            if mode == "client":
                urllib.request.urlopen(base + "/api/status", timeout=5).read()
                urllib.request.urlopen(base + "/api/plants", timeout=5).read()
            metrics = urllib.request.urlopen(base + "/metrics", timeout=5).read().decode()
            open(prefix + ".metrics", "w").write(metrics)
        i += 1
        next_t += 0.1
        time.sleep(max(0.0, next_t - time.monotonic()))
        open(prefix + ".jpegs", "w").write(str(jpegs))
except Exception:
    pass
PY
  client_pid=$!
  wait "$pid" || { tail -3 "$log"; exit 1; }
  [ -n "$client_pid" ] && { kill "$client_pid" 2>/dev/null || true; wait "$client_pid" 2>/dev/null || true; client_pid=; }
  local total p50 p99 drops
  total=$(grep "total:" "$log" | tail -1)
  p50=$(sed -n 's/.*| latency p50 \([0-9.]*\) p99 \([0-9.]*\) ms.*/\1/p' <<<"$total")
  p99=$(sed -n 's/.*| latency p50 \([0-9.]*\) p99 \([0-9.]*\) ms.*/\2/p' <<<"$total")
  drops=$(sed -n 's/.*drops: ring_full \([0-9]*\), overwritten \([0-9]*\), results_full \([0-9]*\).*/\1+\2+\3/p' <<<"$total")
  drops=$((drops))
  local jpegs=0
  [ -f "$out/$mode-$round.jpegs" ] && jpegs=$(cat "$out/$mode-$round.jpegs")
  # The processing thread's cycle (detect, classes, the live view's hand-over): mean and p99.
  local cycle
  cycle=$(/usr/bin/python3 - "$out/$mode-$round.metrics" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
buckets = [(float("inf") if le == "+Inf" else float(le), float(v)) for le, v in
           re.findall(r'stemd_thread_cycle_seconds_bucket\{thread="processing",le="([^"]+)"\} (\S+)', text)]
total = float(re.search(r'stemd_thread_cycle_seconds_sum\{thread="processing"\} (\S+)', text).group(1))
count = float(re.search(r'stemd_thread_cycle_seconds_count\{thread="processing"\} (\S+)', text).group(1))
p99 = next(le for le, v in sorted(buckets) if v >= 0.99 * count)
print(f"{1e3 * total / count:.3f} {1e3 * p99:.1f}")
PY
)
  printf '%-9s round %d: capture->result p50 %s p99 %s ms, drops %d, late %s, processing cycle mean %s ms p99 <= %s ms%s\n' \
    "$mode" "$round" "$p50" "$p99" "$drops" "$(sed -n 's/.*late \([0-9]*\) (worst.*/\1/p' <<<"$total")" \
    ${cycle% *} ${cycle#* } "$([ "$mode" = client ] && echo ", client got $jpegs JPEGs")"
  echo "$mode $p50 $p99 $drops $cycle" >>"$out/results"
}

for round in $(seq "$rounds"); do
  run none "$round"
  run client "$round"
done
/usr/bin/python3 - "$out/results" <<'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
for mode in ("none", "client"):
    r = [(float(a), float(b), int(c), float(d), float(e)) for m, a, b, c, d, e in rows if m == mode]
    p50 = [x[0] for x in r]; p99 = [x[1] for x in r]; drops = sum(x[2] for x in r)
    cycle = [x[3] for x in r]; cycle99 = [x[4] for x in r]
    print(f"{mode:7s}: p50 median {statistics.median(p50):.2f} ms ({min(p50):.2f}-{max(p50):.2f}), "
          f"p99 median {statistics.median(p99):.2f} ms ({min(p99):.2f}-{max(p99):.2f}), drops {drops}; "
          f"processing cycle mean median {statistics.median(cycle):.3f} ms ({min(cycle):.3f}-{max(cycle):.3f}), "
          f"p99 bound median {statistics.median(cycle99):.1f} ms ({min(cycle99):.1f}-{max(cycle99):.1f})")
none = statistics.median(float(r[2]) for r in rows if r[0] == "none")
client = statistics.median(float(r[2]) for r in rows if r[0] == "client")
print(f"p99 growth with a client (medians): {client - none:+.2f} ms (target <= +0.5 ms)")
PY
