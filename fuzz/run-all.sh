#!/usr/bin/env bash
# Runs each fuzz target for SECONDS (default 600) one after another, then keeps what it found.
# Needs cargo-fuzz (cargo install cargo-fuzz), zstd and GNU tar. The stable toolchain accepts the
# nightly flags cargo fuzz passes when RUSTC_BOOTSTRAP=1.
#
# Seeds: seeds/TARGET.tar.zst (committed: the inputs that reached new code in earlier runs,
# findings included, packed because they are hundreds of near-identical files: 12 MB of LAS
# inputs pack into 70 kB) and the crafted corpus of the target's formats
# (crates/myriad/tests/corpus). New inputs go to corpus/TARGET (not committed); after the run,
# those that add coverage are merged into the seeds and packed again; `cargo test` replays them
# (crates/myriad/tests/fuzz_replay.rs): commit seeds/. A crash is written to artifacts/TARGET/;
# copy it into seeds-work/TARGET and pack once it is fixed.
#
# -malloc_limit_mb is set just above 4 GiB: the laz crate sizes each LAZ 1.4 layer buffer from an
# untrusted u32 (vec![0; n], at most 4 GiB, committed lazily by the OS and abandoned when the read
# hits the end of the input). libFuzzer would report that single allocation as out-of-memory;
# anything larger is still reported, and -rss_limit_mb still catches real memory growth.
set -u
cd "$(dirname "$0")"
secs=${1:-600}
crafted=../crates/myriad/tests/corpus
for t in ${TARGETS:-las ply pcd e57 dataset filter shape import query cloud edits}; do
  case $t in
    las) formats="las laz" ;;
    dataset) formats="myr" ;;
    *) formats=$t ;;
  esac
  dirs=""
  for f in $formats; do [ -d $crafted/$f ] && dirs="$dirs $crafted/$f"; done
  rm -rf seeds-work/$t
  mkdir -p corpus/$t seeds-work/$t
  [ -f seeds/$t.tar.zst ] && tar -x --zstd -f seeds/$t.tar.zst -C seeds-work/$t
  RUSTC_BOOTSTRAP=1 cargo fuzz run -O $t corpus/$t seeds-work/$t $dirs -- -max_total_time=$secs \
    -rss_limit_mb=3072 -malloc_limit_mb=4200 -timeout=20 > "fuzz-$t.log" 2>&1
  status=$?
  echo "$t: exit $status $(grep -E '^(Done|==|SUMMARY)' "fuzz-$t.log" | tail -2 | tr '\n' ' ')"
  RUSTC_BOOTSTRAP=1 cargo fuzz run -O $t seeds-work/$t corpus/$t -- -merge=1 > "merge-$t.log" 2>&1
  mkdir -p seeds
  tar -c --sort=name --mtime=@0 --owner=0 --group=0 --numeric-owner -C seeds-work/$t . |
    zstd -19 -q -f -o seeds/$t.tar.zst
  echo "$t: seeds now $(ls seeds-work/$t | wc -l) files, $(stat -c %s seeds/$t.tar.zst) bytes packed"
done
