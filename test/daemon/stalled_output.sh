#!/usr/bin/env bash
# The detections CSV on a file that stops taking writes, as a stalled disk
# does: a FIFO held open by this script and not read, so write(2) blocks
# once its 64 KiB are full. The writer thread waits; the actuator does not:
# frames keep going out and HEARTBEATs keep coming while no line is
# written. Once the FIFO is read again every row arrives whole, none lost.
# Then again with a FIFO that is never read: a SIGTERM still ends stemd,
# after RecordWriter::kCloseTimeoutNs (3 s), exit 1, the rows given up named.
#   stalled_output.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"

synth_strip "$tmp/strip" 1500
mkfifo "$tmp/d.fifo"
# Read and write, so that opening it neither blocks here nor in stemd.
exec 3<>"$tmp/d.fifo"
# Looping: the run goes on until the SIGTERM below.
"$stemd" --config "$src/config/stemd.yaml" --replay "$tmp/strip" --detections-csv "$tmp/d.fifo" \
  --can-log "$tmp/can.log" --set status.interval_s=0.5 2>"$tmp/err" &
pid=$!
alive() { kill -0 "${pid%% *}" 2>/dev/null || fail "stemd exited: $(tail -5 "$tmp/err")"; }

# Rows were written, then an interval with frames out and no row written:
# the FIFO is full and the writer waits in write(2).
stalled() {
  awk '/files: lines written [1-9]/ { wrote = 1 }
       wrote && /out [1-9][0-9.]* fps/ && /files: lines written 0, lost 0/ { found = 1 }
       END { exit !found }' "$tmp/err"
}
for _ in $(seq 600); do stalled && break; alive; sleep 0.1; done
stalled || fail "no status line with frames out and no row written within 60 s: $(grep -c 'files:' "$tmp/err") status lines, the last: $(grep 'files:' "$tmp/err" | tail -1)"
echo "stalled: $(grep 'files: lines written 0, lost 0' "$tmp/err" | grep -m1 -oE 'out [0-9.]+ fps')"

# While it stays full, the actuator thread still serves the bus.
heartbeats() { grep -c ' can0 303#' "$tmp/can.log" || true; }
before=$(heartbeats)
for _ in $(seq 300); do [ "$(heartbeats)" -ge $((before + 10)) ] && break; alive; sleep 0.1; done
[ "$(heartbeats)" -ge $((before + 10)) ] || fail "HEARTBEATs stopped while the CSV was stalled: $before, then $(heartbeats)"
echo "HEARTBEATs while stalled: $before, then $(heartbeats)"

# Read it again, stop stemd: every row the writer took arrives.
# (Without this script's read-write descriptor: holding it, the reader
# would never see the end.)
cat "$tmp/d.fifo" >"$tmp/d.csv" 3<&- &
reader=$!
pid="$pid $reader"
exec 3<&-
kill -TERM "${pid%% *}"
wait "${pid%% *}" || fail "stemd exited $? after SIGTERM: $(tail -3 "$tmp/err")"
wait "$reader"
written=$(sed -n 's/.*total: .*files: lines written \([0-9]*\), lost \([0-9]*\).*/\1 \2/p' "$tmp/err")
[ -n "$written" ] || fail "no files: counts in the summary: $(grep total: "$tmp/err")"
set -- $written
rows=$(($(wc -l <"$tmp/d.csv") - 1))
[ "$2" = 0 ] || fail "$2 rows lost"
[ "$rows" = "$1" ] || fail "the CSV has $rows rows, the summary says $1 written"
[ "$(head -1 "$tmp/d.csv")" = "t_ns,image,plant,x,y,method,leaves,area_px,estimator,confidence" ] || fail "header"
[ -z "$(tail -c 1 "$tmp/d.csv")" ] || fail "the CSV ends on a torn row"
echo "drained: $rows rows, none lost"

# A FIFO that is never read again: the stop gives the rows up and exits.
mkfifo "$tmp/e.fifo"
exec 4<>"$tmp/e.fifo"
"$stemd" --config "$src/config/stemd.yaml" --replay "$tmp/strip" --detections-csv "$tmp/e.fifo" \
  --can-log "$tmp/can2.log" --set status.interval_s=0.5 2>"$tmp/err" &
pid=$!
for _ in $(seq 600); do stalled && break; alive; sleep 0.1; done
stalled || fail "the second run did not stall within 60 s"
t0=$(date +%s%N)
kill -TERM "$pid"
set +e
for _ in $(seq 300); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
kill -0 "$pid" 2>/dev/null && fail "stemd still runs 30 s after SIGTERM with its CSV stalled: $(tail -3 "$tmp/err")"
wait "$pid"; rc=$?
set -e
stop_ms=$((($(date +%s%N) - t0) / 1000000))
exec 4<&-
[ "$rc" = 1 ] || fail "exited $rc after a stalled stop, want 1: $(tail -3 "$tmp/err")"
grep -q "e.fifo: [0-9]* lines not written: the file did not take them within 3000 ms" "$tmp/err" || fail "no line giving the rows up: $(tail -5 "$tmp/err")"
grep -q "exiting with an output file stalled" "$tmp/err" || fail "no closing line: $(tail -3 "$tmp/err")"
grep -qE "total: .*files: lines written [0-9]+, lost [1-9]" "$tmp/err" || fail "the summary counts no lost row: $(grep total: "$tmp/err")"
echo "stalled stop: exit 1 after $stop_ms ms"
tail -4 "$tmp/err" | cut -c1-200
echo "stalled_output: ok"
