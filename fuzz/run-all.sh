#!/usr/bin/env bash
# Runs each fuzz target for SECONDS (default 600) one after another, then keeps what it found.
# Needs cargo-fuzz (cargo install cargo-fuzz). The stable toolchain accepts the nightly flags
# cargo fuzz passes when RUSTC_BOOTSTRAP=1.
#
# Seeds: seeds/TARGET (committed: the inputs that reached new code in earlier runs, findings
# included) and the crafted corpus of the target's formats (crates/myriad/tests/corpus). New
# inputs go to corpus/TARGET (not committed); after the run, those that add coverage are merged
# into seeds/TARGET, which `cargo test` replays (crates/myriad/tests/fuzz_replay.rs): commit it.
# A crash is written to artifacts/TARGET/; copy it into seeds/TARGET once fixed.
#
# -malloc_limit_mb is set just above 4 GiB: the laz crate sizes each LAZ 1.4 layer buffer from an
# untrusted u32 (vec![0; n], at most 4 GiB, committed lazily by the OS and abandoned when the read
# hits the end of the input). libFuzzer would report that single allocation as out-of-memory;
# anything larger is still reported, and -rss_limit_mb still catches real memory growth.
set -u
cd "$(dirname "$0")"
secs=${1:-600}
crafted=../crates/myriad/tests/corpus
for t in las ply pcd e57 dataset; do
  case $t in
    las) formats="las laz" ;;
    dataset) formats="myr" ;;
    *) formats=$t ;;
  esac
  dirs=""
  for f in $formats; do dirs="$dirs $crafted/$f"; done
  mkdir -p corpus/$t seeds/$t
  RUSTC_BOOTSTRAP=1 cargo fuzz run -O $t corpus/$t seeds/$t $dirs -- -max_total_time=$secs \
    -rss_limit_mb=3072 -malloc_limit_mb=4200 -timeout=20 > "fuzz-$t.log" 2>&1
  status=$?
  echo "$t: exit $status $(grep -E '^(Done|==|SUMMARY)' "fuzz-$t.log" | tail -2 | tr '\n' ' ')"
  RUSTC_BOOTSTRAP=1 cargo fuzz run -O $t seeds/$t corpus/$t -- -merge=1 > "merge-$t.log" 2>&1
  echo "$t: seeds now $(ls seeds/$t | wc -l) files"
done
