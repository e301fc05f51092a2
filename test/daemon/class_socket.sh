#!/usr/bin/env bash
# End to end with classify.provider socket: a stand-in peer
# (stemd-test-class-peer) gets each replayed frame's message from stemd and
# answers with that frame's class map from the recording (at a quarter of
# its size), while frames.csv itself has no class column.
#  - serving: no command near anything but a weed, some weeds commanded,
#    no crop sent, no timeout; the peer's one malformed message is counted
#    and dropped, and its hang-up halfway is survived (a second peer).
#  - answering too late, or never: every plant unknown, none commanded,
#    every frame counted in class_timeouts.
# Usage: class_socket.sh STEMD TOOLS_DIR SOURCE_DIR PEER
set -euo pipefail
stemd=$1 tools=$2 src=$3 peer=$4
. "$(dirname "$0")/../support/script.sh"

synth_strip "$tmp/strip" 1500
drop_class_column "$tmp/strip"
frames=$(($(wc -l <"$tmp/strip/frames.csv") - 1))
sock="$tmp/classes.sock"

# run NAME TIMEOUT_MS PEER_ARGS...: the peer in the background (it waits for
# the socket), then stemd on the strip; the peer ends when stemd hangs up.
run() {
  local name=$1 timeout_ms=$2
  shift 2
  "$peer" "$sock" "$tmp/strip" "$@" >"$tmp/$name.peer" 2>&1 &
  local peer_pid=$!
  pid="$pid $peer_pid"
  "$stemd" --config "$src/config/stemd.yaml" --set classify.provider=socket --set classify.socket="$sock" \
    --set classify.provider_timeout_ms="$timeout_ms" --replay "$tmp/strip" --once \
    --can-log "$tmp/$name.log" --map "$tmp/$name.jsonl" 2>"$tmp/$name.err" ||
    fail "stemd ($name) exited $?: $(tail -5 "$tmp/$name.err")"
  wait "$peer_pid" || fail "the peer ($name) exited $?: $(cat "$tmp/$name.peer")"
  total=$(grep 'total:' "$tmp/$name.err" | tail -1)
  [ -n "$total" ] || fail "no total line ($name)"
}
# count NAME FIELD: a figure of the classes part of the total line.
count() { sed -n "s/.*classes: .*$2 \([0-9]*\).*/\1/p" <<<"$total"; }

# One provider: a socket without its path, the model provider without a
# model, or a model beside another provider, is refused at start (exit 2).
refused() {
  local why=$1
  shift
  set +e
  "$stemd" --config "$src/config/stemd.yaml" "$@" --replay "$tmp/strip" --once --check-config >/dev/null 2>"$tmp/refused"
  local rc=$?
  set -e
  [ $rc -eq 2 ] || fail "$why: exit $rc"
  grep -q "$why" "$tmp/refused" || fail "$why: $(cat "$tmp/refused")"
}
refused "socket needs classify.socket" --set classify.provider=socket
refused "model needs classify.model" --set classify.provider=model
refused "classify.provider is not model" --set classify.provider=socket --set classify.socket="$sock" \
  --set classify.model="$tmp/any.yaml"
"$stemd" --config "$src/config/stemd.yaml" --set classify.provider=socket --set classify.socket="$sock" \
  --replay "$tmp/strip" --once --check-config >/dev/null || fail "a socket provider's configuration was refused"

# Serving, with one malformed message first and a hang-up after 10 frames.
run serve 2000 serve --garbage --reconnect-after 10
grep -q "listening on $sock" "$tmp/serve.err" || fail "the socket is not named at start"
grep -q "hung up" "$tmp/serve.err" || fail "the peer's hang-up was not logged"
[ "$(count serve class_timeouts)" = 0 ] || fail "timeouts while the peer answered: $total"
[ "$(count serve bad_messages)" = 1 ] || fail "the malformed message was not counted once: $total"
[ "$(count serve peers)" = 2 ] || fail "the peer was not taken again: $total"
maps=$(count serve maps)
[ "$maps" -ge "$frames" ] || fail "$maps class maps for $frames frames: $total"
score_weeds_only "$tmp/strip" "$tmp/serve.log" "$tmp/serve.jsonl" "$src/config/stemd.yaml"
grep -q '"class":"weed"' "$tmp/serve.jsonl" || fail "no plant classed weed in the map"

# Too late (each map 200 ms after its frame, the timeout 20 ms), and never.
for mode in late never; do
  run "$mode" 20 "$mode" --late-ms 200
  timeouts=$(count "$mode" class_timeouts)
  frames_out=$(sed -n 's/.* \([0-9]*\) out,.*/\1/p' <<<"$total")
  [ -n "$timeouts" ] && [ "$timeouts" -gt 0 ] && [ "$timeouts" = "$frames_out" ] ||
    fail "$mode: $timeouts timeouts for $frames_out frames: $total"
  if grep -q '"reason":"sent"' "$tmp/$mode.jsonl"; then fail "$mode: a plant was sent"; fi
  if grep -q '"class":"\(crop\|weed\)"' "$tmp/$mode.jsonl"; then fail "$mode: a plant was classed"; fi
  grep -q '"class":"unknown"' "$tmp/$mode.jsonl" || fail "$mode: no plant in the map"
  grep -q ' sent 0,' <<<"$total" || fail "$mode: a TARGET was sent: $total"
done
echo "PASS: $frames frames, $matched weeds treated, no crop commanded; late and never: every frame timed out, nothing commanded"
