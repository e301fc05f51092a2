#!/usr/bin/env bash
# /metrics of a running stemd parses as Prometheus text format 0.0.4 with the
# reference parser (Debian python3-prometheus-client), every family the
# README names is there, and the histograms are whole (+Inf = _count); with
# the in-box model, its weed targets and the cells over classify.max_cells.
#   metrics.sh STEMD TOOLS_DIR SOURCE_DIR
. "$(dirname "$0")/common.sh" "$@"
/usr/bin/python3 -c "import prometheus_client.parser" 2>/dev/null \
  || { echo "SKIP: python3-prometheus-client (the reference parser) is not installed"; exit 77; }

# fetch_until FILE PATTERN: /metrics into FILE until a line matches PATTERN
# (at most 60 s; the checks after it then say what is missing).
fetch_until() {
  for _ in $(seq 300); do
    fetch /metrics "$1"
    grep -q "$2" "$1" && break
    sleep 0.2
  done
}

"$tools/stemd-synth" --out "$tmp/rec" --preset late --frames 10 --fps 10 >/dev/null
start_stemd "$tmp/err" --config "$src/config/stemd.yaml" --replay "$tmp/rec" --can-log "$tmp/can.log" \
  --map "$tmp/map.jsonl" --set web.listen=127.0.0.1:0
# Wait until frames went through, so the histograms have counts.
fetch_until "$tmp/metrics" '^stemd_frames_out_total [1-9]'
/usr/bin/python3 - "$tmp/metrics" <<'PY' || fail "metrics check"
import sys
from prometheus_client.parser import text_string_to_metric_families
text = open(sys.argv[1]).read()
families = {f.name: f for f in text_string_to_metric_families(text)}
want = {
    "stemd_frames_in": "counter", "stemd_frames_out": "counter", "stemd_frames_dropped": "counter",
    "stemd_deadline_misses": "counter", "stemd_targets": "counter", "stemd_bus_errors": "counter",
    "stemd_heartbeat_misses": "counter", "stemd_file_lines": "counter",
    "stemd_capture_to_result_seconds": "histogram", "stemd_capture_to_send_seconds": "histogram",
    "stemd_thread_cycle_seconds": "histogram", "stemd_pipeline_seconds": "histogram",
}
bad = [f"{n}: {t}" for n, t in want.items() if n not in families or families[n].type != t]
if bad:
    sys.exit("missing or mistyped: " + ", ".join(bad))
causes = {s.labels["cause"] for s in families["stemd_frames_dropped"].samples}
if causes != {"ring_full", "overwritten", "results_full", "corrupt", "bad_size", "failed"}:
    sys.exit(f"drop causes: {causes}")
outcomes = {s.labels["outcome"] for s in families["stemd_file_lines"].samples}
if outcomes != {"written", "lost"}:
    sys.exit(f"file line outcomes: {outcomes}")
if "stemd_trigger_pulses" in families:
    sys.exit("trigger series without a trigger line")
threads = {s.labels.get("thread") for s in families["stemd_thread_cycle_seconds"].samples}
if threads != {"capture", "processing", "actuator"}:
    sys.exit(f"threads: {threads}")
for name in ("stemd_capture_to_result_seconds", "stemd_pipeline_seconds"):
    samples = families[name].samples
    buckets = [s.value for s in samples if s.name.endswith("_bucket")]
    count = [s.value for s in samples if s.name.endswith("_count")][0]
    if buckets != sorted(buckets) or buckets[-1] != count or count <= 0:
        sys.exit(f"{name}: buckets {buckets}, count {count}")
print(f"metrics: {len(families)} families parse")
PY

# With the in-box model and a budget of 20 cells a frame: the model's
# series, with cells over the budget counted, and no socket series.
stop_stemd
"$tools/stemd-synth" --strip --out "$tmp/train" --preset early --seed 6 --fragment 0 --length-mm 1500 \
  --fps 15 --speed-kmh 2.5 >/dev/null
"$tools/stemd-train" --out "$tmp/model.yaml" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg \
  --folds 3 --trees 30 --cell-trees 10 --cell-samples 6000 "$tmp/train" >"$tmp/train.txt" 2>&1 ||
  fail "stemd-train exited $?: $(tail -3 "$tmp/train.txt")"
start_stemd "$tmp/model.err" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg \
  --set classify.model="$tmp/model.yaml" --set classify.max_cells=20 --replay "$tmp/train" --can-log "$tmp/model.log" \
  --set web.listen=127.0.0.1:0
fetch_until "$tmp/model.metrics" '^stemd_classifier_cells_over_budget_total [1-9]'
/usr/bin/python3 - "$tmp/model.metrics" <<'PY' || fail "metrics with a model: $(grep -E 'weed_targets|classifier|class_' "$tmp/model.metrics")"
import sys
from prometheus_client.parser import text_string_to_metric_families
families = {f.name: f for f in text_string_to_metric_families(open(sys.argv[1]).read())}
for name in ("stemd_weed_targets", "stemd_classifier_cells_over_budget", "stemd_classifier_frames_over_budget",
             "stemd_bad_class_plants"):
    if name not in families or families[name].type != "counter":
        sys.exit(f"missing or mistyped: {name}")
kinds = {s.labels["kind"] for s in families["stemd_weed_targets"].samples}
if kinds != {"part", "stemless", "cover"}:
    sys.exit(f"weed target kinds: {kinds}")
over = [s.value for s in families["stemd_classifier_cells_over_budget"].samples if s.name.endswith("_total")]
frames = [s.value for s in families["stemd_classifier_frames_over_budget"].samples if s.name.endswith("_total")]
if not over or over[0] <= 0 or not frames or frames[0] <= 0:
    sys.exit(f"cells over a budget of 20: {over} in {frames} frames")
if "stemd_class_maps" in families:
    sys.exit("socket series without a socket provider")
PY

# With the socket provider and a peer that serves each frame's class map
# from the recording (whose frames.csv then loses its class column): the
# socket's series, maps and the peer counted, and no model series.
peer=${4:-}
if [ -z "$peer" ]; then
  echo "metrics: ok (the socket provider's series not checked: no class peer given)"
  exit 0
fi
stop_stemd
drop_class_column "$tmp/train"
sock=$tmp/classes.sock
"$peer" "$sock" "$tmp/train" serve >"$tmp/peer.out" 2>&1 &
peer_pid=$!
start_stemd "$tmp/socket.err" --config "$src/config/stemd.yaml" --set segment.method=chromatic_exg \
  --set classify.provider=socket --set classify.socket="$sock" --replay "$tmp/train" --can-log "$tmp/socket.log" \
  --set web.listen=127.0.0.1:0
fetch_until "$tmp/socket.metrics" '^stemd_class_maps_total [1-9]'
/usr/bin/python3 - "$tmp/socket.metrics" <<'PY' || fail "metrics with the socket provider: $(grep -E 'class_|classifier' "$tmp/socket.metrics")"
import sys
from prometheus_client.parser import text_string_to_metric_families
families = {f.name: f for f in text_string_to_metric_families(open(sys.argv[1]).read())}
def total(name):
    if name not in families or families[name].type != "counter":
        sys.exit(f"missing or mistyped: {name}")
    values = [s.value for s in families[name].samples if s.name.endswith("_total")]
    if len(values) != 1:
        sys.exit(f"{name}: {len(values)} samples")
    return values[0]
maps, peers = total("stemd_class_maps"), total("stemd_class_peers")
total("stemd_class_timeouts")
bad = total("stemd_class_bad_messages")
if maps <= 0 or peers != 1 or bad != 0:
    sys.exit(f"{maps} maps from {peers} peers with {bad} bad messages: one well-behaved peer served")
for name in ("stemd_classifier_cells_over_budget", "stemd_weed_targets"):
    if name in families:
        sys.exit(f"model series without a model: {name}")
PY
stop_stemd
wait "$peer_pid" || fail "the peer exited $?: $(cat "$tmp/peer.out")"
echo "metrics: ok"
