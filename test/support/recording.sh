# shellcheck shell=bash
# Sourced by test/support/script.sh and test/web/common.sh (both define fail).

# drop_class_column DIR: a generated strip's frames.csv without its class
# column (t_ns,rgb,nir,mask,odom_mm), so that the classes come from a
# provider, not the recording.
drop_class_column() {
  head -1 "$1/frames.csv" | grep -q '^t_ns,rgb,nir,mask,odom_mm,class$' || fail "unexpected strip columns in $1"
  awk -F, -v OFS=, '{ NF = 5; print }' "$1/frames.csv" >"$1/frames.csv.new"
  mv "$1/frames.csv.new" "$1/frames.csv"
}
