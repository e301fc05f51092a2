#!/usr/bin/env bash
# A file-size limit (ulimit -f) reached by the CAN log and the plant map:
# stemd names the file and the error (EFBIG), counts the lost frames and
# exits 1, instead of dying of SIGXFSZ without a word.
#   file_size_limit.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 tools=$2 src=$3
. "$(dirname "$0")/../support/script.sh"

# 3 m at 2.5 km/h: a paced replay of 4.3 s, whose HEARTBEATs alone (every
# 100 ms, ~45 bytes a line) pass the 1 KiB limit however many TARGETs a
# loaded machine gets out in time.
synth_strip "$tmp/strip" 3000
# stderr goes through a pipe to a cat outside the limit: a file would be
# held to the limit too and lose stemd's last lines.
set +e
(
  ulimit -f 1   # 1024 bytes: a few CAN log lines
  exec "$stemd" --config "$src/config/stemd.yaml" --replay "$tmp/strip" --once --can-log "$tmp/can.log" \
    --map "$tmp/map.jsonl"
) 2>&1 >/dev/null | cat >"$tmp/err"
rc=${PIPESTATUS[0]}
set -e
[ $rc -eq 1 ] || fail "exited $rc (153 = killed by SIGXFSZ): $(tail -3 "$tmp/err")"
grep -q "can.log: write failed: File too large" "$tmp/err" || fail "no CAN log error: $(cat "$tmp/err")"
grep -q "frames could not be written" "$tmp/err" || fail "no closing error line: $(tail -3 "$tmp/err")"
# What was written is whole lines.
[ -z "$(tail -c 1 "$tmp/can.log")" ] || fail "the CAN log ends in a torn line"
echo "file_size_limit: ok"
