#!/usr/bin/env bash
# A file-size limit (ulimit -f) reached by the CAN log and the plant map:
# stemd names the file and the error (EFBIG), counts the lost frames and
# exits 1, instead of dying of SIGXFSZ without a word.
#   file_size_limit.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$tools/stemd-synth" --strip --out "$tmp/strip" --preset early --seed 5 --fragment 0 --length-mm 1000 \
  --fps 15 --speed-kmh 2.5 >/dev/null
rc=0
(
  ulimit -f 1   # 1024 bytes: a few CAN log lines
  exec "$stemd" --config "$src/config/stemd.yaml" --replay "$tmp/strip" --once --can-log "$tmp/can.log" \
    --map "$tmp/map.jsonl"
) 2>"$tmp/err" || rc=$?
[ $rc -eq 1 ] || fail "exited $rc (153 = killed by SIGXFSZ): $(tail -3 "$tmp/err")"
grep -q "can.log: write failed: File too large" "$tmp/err" || fail "no CAN log error: $(cat "$tmp/err")"
grep -q "frames could not be written" "$tmp/err" || fail "no closing error line: $(tail -3 "$tmp/err")"
# What was written is whole lines.
[ -z "$(tail -c 1 "$tmp/can.log")" ] || fail "the CAN log ends in a torn line"
echo "file_size_limit: ok"
