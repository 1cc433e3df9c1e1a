#!/usr/bin/env bash
# Runs each fuzz target for SECONDS (default 600) one after another; seeds come from corpus/.
# Needs cargo-fuzz (cargo install cargo-fuzz). The stable toolchain accepts the nightly flags
# cargo fuzz passes when RUSTC_BOOTSTRAP=1.
set -u
cd "$(dirname "$0")"
secs=${1:-600}
for t in las ply pcd e57; do
  mkdir -p corpus/$t
  RUSTC_BOOTSTRAP=1 cargo fuzz run -O $t corpus/$t -- -max_total_time=$secs -rss_limit_mb=3072 -timeout=20 \
    > "fuzz-$t.log" 2>&1
  echo "$t: exit $? $(grep -E '^(Done|==|SUMMARY)' "fuzz-$t.log" | tail -2 | tr '\n' ' ')"
done
