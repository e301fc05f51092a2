#!/usr/bin/env bash
# stemd's command line: --help anywhere, the usage errors (one line naming
# the option, then the usage, exit 2), an option given twice keeps the last.
#   command_line.sh STEMD TOOLS_DIR SOURCE_DIR
set -euo pipefail
stemd=$1 src=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# Runs stemd with the arguments; $rc, $tmp/out and $tmp/err hold the result.
run() { rc=0; "$stemd" "$@" >"$tmp/out" 2>"$tmp/err" || rc=$?; }

for help in --help -h "--set --help" "--config -h" "--bogus --help"; do
  # shellcheck disable=SC2086
  run $help
  [ $rc -eq 0 ] && head -1 "$tmp/out" | grep -q "^usage: stemd \[--config FILE\]" || fail "$help: exit $rc $(cat "$tmp/out" "$tmp/err")"
  grep -q -- "--map-geojson" "$tmp/out" || fail "$help: the usage lists every option"
done

# A usage error: "stemd: MESSAGE", then the usage on stderr; exit 2.
expect_usage_error() {
  local message=$1; shift
  run "$@"
  [ $rc -eq 2 ] || fail "$*: exit $rc, not 2"
  [ "$(head -1 "$tmp/err")" = "stemd: $message" ] || fail "$*: $(head -1 "$tmp/err")"
  sed -n 2p "$tmp/err" | grep -q "^usage: stemd " || fail "$*: no usage after the error"
  [ ! -s "$tmp/out" ] || fail "$*: wrote to stdout"
}
expect_usage_error "unknown argument --bogus" --check-config --bogus
expect_usage_error "unknown argument stray" stray
for option in --config --set --replay --detections-csv --can-log --map --map-geojson; do
  expect_usage_error "$option needs a value" --check-config "$option"
done
expect_usage_error "--config needs a file name, got ''" --config "" --check-config

# A configuration error is one line, without the usage; exit 2.
run --check-config --set ring.capacity=0
[ $rc -eq 2 ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] ||
  fail "configuration error: exit $rc $(cat "$tmp/err")"

# --set applies in the order given: the first bad one is the error.
run --set ring.capacity=8 --set ring.capacity=0 --set ring.capacity=65 --check-config
[ $rc -eq 2 ] && grep -q "^stemd: --set ring.capacity=0: " "$tmp/err" || fail "--set in order: exit $rc $(cat "$tmp/err")"

# The last of a repeated option wins; a flag may be given twice; '-' is a value.
mkdir "$tmp/empty"
run --replay "$tmp/nowhere" --replay "$tmp/empty" --once --once --check-config
[ $rc -eq 2 ] && grep -q "$tmp/empty is not a recording directory" "$tmp/err" || fail "last --replay: $(cat "$tmp/err")"
run --config "$src/config/stemd.yaml" --can-log - --detections-csv - --check-config --check-config
[ $rc -eq 0 ] && grep -q "configuration ok" "$tmp/out" || fail "'-' as a value: exit $rc $(cat "$tmp/err")"
echo "ok"
