#!/usr/bin/env bash
# Runs each fuzz target for SECONDS (default 600) one after another; seeds come from corpus/.
# Needs cargo-fuzz (cargo install cargo-fuzz). The stable toolchain accepts the nightly flags
# cargo fuzz passes when RUSTC_BOOTSTRAP=1.
#
# -malloc_limit_mb is set just above 4 GiB: the laz crate sizes each LAZ 1.4 layer buffer from an
# untrusted u32 (vec![0; n], at most 4 GiB, committed lazily by the OS and abandoned when the read
# hits the end of the input). libFuzzer would report that single allocation as out-of-memory;
# anything larger is still reported, and -rss_limit_mb still catches real memory growth.
set -u
cd "$(dirname "$0")"
secs=${1:-600}
for t in las ply pcd e57 dataset; do
  mkdir -p corpus/$t
  RUSTC_BOOTSTRAP=1 cargo fuzz run -O $t corpus/$t -- -max_total_time=$secs -rss_limit_mb=3072 -malloc_limit_mb=4200 -timeout=20 \
    > "fuzz-$t.log" 2>&1
  echo "$t: exit $? $(grep -E '^(Done|==|SUMMARY)' "fuzz-$t.log" | tail -2 | tr '\n' ' ')"
done
