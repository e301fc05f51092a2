#!/usr/bin/env bash
# The speed of the default pipeline on every real data set in DATA_DIR, in
# one table: each set's frame time (stemd-detect --timing, the median over
# its frames) in ms, in cvtColor passes (stemd-bench's yardstick of the
# machine, timed in the same round) and against the paper's published
# 62.2 ms a frame; and the crop/weed classifier's stage on CWFID's frames
# with the example model. A measurement, not a test: nothing fails on a
# slow machine.
#   tools/bench-real.sh [DATA_DIR] [OUT_DIR]    (defaults: ../shared/data, out/bench-real)
#   STEMD_BENCH_RUNS=N   rounds (default 3); the sets take turns in each
#                        round, so a noisy neighbour spreads over all of them
# Every folder is a set by its layout, whatever its name (tools/real-sets.sh:
# CWFID's images/ and masks/, or a recording; RGB+NIR recordings are also
# timed from RGB alone), at the GSD of its source or STEMD_EVAL_GSD.
# The tools come from $STEMD_TOOLS, else build/release/tools (built first
# when missing). Makes each CWFID set's recording, and the example model
# (tools/cwfid-model.sh on DATA_DIR/cwfid-train, about a minute) when
# out/models/cwfid.yaml is absent.
# Exit 0 when the table was made; 77 (skip) when DATA_DIR is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-../shared/data}
out=${2:-out/bench-real}
runs=${STEMD_BENCH_RUNS:-3}
if [ ! -d "$data" ]; then
  echo "bench-real: $data is absent: no real frames to time (see README, Benchmarks)" >&2
  exit 77
fi
if ! [[ "$runs" =~ ^[1-9][0-9]*$ ]]; then
  echo "bench-real: STEMD_BENCH_RUNS must be a positive integer, not '$runs'" >&2
  exit 2
fi
tools=${STEMD_TOOLS:-}
if [ -z "$tools" ]; then
  tools=build/release/tools
  if [ ! -x "$tools/stemd-detect" ] || [ ! -x "$tools/stemd-bench" ]; then
    cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
    cmake --build build/release -j "$(nproc)" --target stemd-detect stemd-bench
  fi
fi
for tool in stemd-detect stemd-bench; do
  [ -x "$tools/$tool" ] || { echo "bench-real: no $tools/$tool" >&2; exit 2; }
done
. tools/real-sets.sh
mkdir -p "$out"
rows="$out/rows.jsonl"
: >"$rows"

# The configurations, one per line: name|configuration|--set arguments|inputs.
# Every folder of DATA_DIR is a set by its layout (tools/real-sets.sh),
# whatever its name; its frames are given several times over (at least
# twice, and until 30 frames), so that each median is over 30 frames or
# more.
repeated() {  # dir frames: the dir as many times as that takes
  local n=$(( (30 + $2 - 1) / $2 )) list="" i
  (( n < 2 )) && n=2
  for ((i = 0; i < n; i++)); do list+="${list:+ }$1"; done
  echo "$list"
}
configs=()
model=out/models/cwfid.yaml
for d in "$data"/*/; do
  d=${d%/}
  name=$(basename "$d")
  layout=$(real_set_layout "$d")
  gsd=$(real_set_gsd "$name" "$layout")
  gsd_set=${gsd:+--set camera.gsd_mm_per_px=$gsd}
  case $layout in
    cwfid)
      c=$out/$name-recording
      tools/cwfid-recording.sh "$d" "$c" >/dev/null
      configs+=("$name|default|$gsd_set|$(repeated "$c" "$(recording_frames "$c")")")
      # The example model is for CWFID's camera: its classifier's stage, once
      # over the frames. It is made from cwfid-train only, never from the
      # set being timed (which may be a test split).
      if [ ! -f "$model" ] && [ "$(real_set_layout "$data/cwfid-train")" = cwfid ]; then
        echo "bench-real: making the example model $model (tools/cwfid-model.sh)" >&2
        tools/cwfid-model.sh "$data/cwfid-train" >"$out/cwfid-model.log" 2>&1
      fi
      if [ -f "$model" ]; then
        configs+=("$name|classifier (example model)|$gsd_set --set classify.model=$model|$c")
      else
        echo "bench-real: $name: no $model (tools/cwfid-model.sh CWFID_TRAIN_DIR makes it): its classifier not timed" >&2
      fi
      ;;
    recording)
      inputs=$(repeated "$d" "$(recording_frames "$d")")
      if recording_has_column "$d" nir; then
        configs+=("$name|rgb+nir, default|$gsd_set|$inputs")
        configs+=("$name|rgb|$gsd_set --set segment.method=chromatic_exg|$inputs")
      else
        configs+=("$name|default|$gsd_set|$inputs")
      fi
      ;;
    *) real_set_skipped bench-real "$name" "$layout" ;;
  esac
done
if [ ${#configs[@]} -eq 0 ]; then
  echo "bench-real: no data set under $data" >&2
  exit 77
fi

cpu=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -1)
load_start=$(cut -d' ' -f1-3 /proc/loadavg)
started=$(date -u +%FT%TZ)

# The yardstick: stemd-bench's cvtColor median, at the start and the end of
# every round.
cvtcolor() {
  local ms
  ms=$("$tools/stemd-bench" --json --benchmark_filter=cvtcolor --repetitions 1000 2>/dev/null |
    sed -n 's/.*"cvtcolor_ms_median":\([0-9.]*\).*/\1/p')
  [ -n "$ms" ] || { echo "bench-real: stemd-bench gave no cvtcolor_ms_median" >&2; exit 1; }
  printf '{"round":%d,"cvtcolor_ms":%s}\n' "$1" "$ms" >>"$rows"
}

for ((round = 1; round <= runs; round++)); do
  cvtcolor "$round"
  for config in "${configs[@]}"; do
    IFS='|' read -r name label sets inputs <<<"$config"
    log="$out/${name}-${label//[ ,()+]/-}-round$round.log"
    # shellcheck disable=SC2086  # word splitting of the --set arguments and inputs is meant
    "$tools/stemd-detect" --config config/stemd.yaml $sets --timing $inputs >/dev/null 2>"$log"
    frame=$(sed -n 's/^timing median over \([0-9]*\) frames: index .* total \([0-9.]*\) ms$/\1 \2/p' "$log")
    classify=$(sed -n 's/^timing median over [0-9]* frames: classify [0-9.]* ms, thread CPU \([0-9.]*\) ms.*/\1/p' "$log")
    [ -n "$frame" ] || { echo "bench-real: no timing in $log" >&2; exit 1; }
    printf '{"set":"%s","config":"%s","round":%d,"frames":%s,"frame_ms":%s,"classify_cpu_ms":%s}\n' \
      "$name" "$label" "$round" "${frame% *}" "${frame#* }" "${classify:-null}" >>"$rows"
  done
  cvtcolor "$round"
done
load_end=$(cut -d' ' -f1-3 /proc/loadavg)

python3 - "$rows" "$cpu" "$(nproc)" "$load_start" "$load_end" "$started" "$(git describe --always --dirty 2>/dev/null || echo "?")" <<'PY'
import json, statistics, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
cpu, cores, load_start, load_end, started, commit = sys.argv[2:8]
PAPER_MS = 62.2  # the paper's own table, an i7-6700HQ: another CPU, so the ratio is indicative
cvt = sorted(r["cvtcolor_ms"] for r in rows if "set" not in r)
rows = [r for r in rows if "set" in r]
keys = []
for r in rows:
    if (r["set"], r["config"]) not in keys:
        keys.append((r["set"], r["config"]))
rounds = max(r["round"] for r in rows)
yardstick = statistics.median(cvt)
print("machine: %s, %s cores; load %s at start, %s at the end; %s; commit %s" % (
    cpu, cores, load_start, load_end, started, commit))
print("cvtColor BGR->GRAY (stemd-bench's yardstick, at each round's start and end): median %.3f ms (%.3f-%.3f)" % (
    yardstick, cvt[0], cvt[-1]))
print("each round's time is the median over its frames; below, the median over %d round%s (their range)," % (
    rounds, "" if rounds == 1 else "s"))
print("and that median in cvtColor passes")
width = max([12] + [len(name) for name, _ in keys])
print("%-*s %-27s %6s  %-9s %-20s %-7s %s" % (width, "set", "configuration", "frames", "stage", "ms", "passes",
                                              "targets"))
for name, config in keys:
    field = "classify_cpu_ms" if config.startswith("classifier") else "frame_ms"
    mine = [r for r in rows if (r["set"], r["config"]) == (name, config) and r[field] is not None]
    if not mine:
        continue
    values = sorted(r[field] for r in mine)
    median = statistics.median(values)
    passes = median / yardstick
    if field == "frame_ms":
        stage = "frame"
        targets = "%.2fx the paper (15x: %s); 8 passes: %s" % (
            PAPER_MS / median, "met" if PAPER_MS / median >= 15 else "missed", "within" if passes <= 8 else "over")
    else:
        stage = "classify"
        targets = "thread CPU; 1 ms: %s" % ("met" if median <= 1.0 else "missed")
    print("%-*s %-27s %6d  %-9s %-20s %-7s %s" % (
        width, name, config, mine[0]["frames"], stage, "%.2f (%.2f-%.2f)" % (median, values[0], values[-1]),
        "%.1f" % passes, targets))
PY
