#!/bin/sh
# Builds the web viewer's WebAssembly into myriad-serve's viewer/ folder (committed there, so that
# `cargo build` needs no WebAssembly target), with a stamp of the sources it was built from.
# `build.sh --check` says whether the committed build is still that of the sources (the tests run
# it). Needs `rustup target add wasm32-unknown-unknown` to build, nothing to check.
set -eu
cd "$(dirname "$0")/../.."
out=crates/myriad-serve/viewer
stamp() {
    # The crates compiled into it and the workspace manifest (its versions and the wasm profile).
    find crates/myriad-core crates/myriad-format crates/myriad-measure crates/myriad-lod crates/myriad-web \
        \( -name '*.rs' -o -name Cargo.toml \) -not -path '*/tests/*' | LC_ALL=C sort |
        while read -r f; do printf '%s\n' "$f"; cat "$f"; done | cat - Cargo.toml |
        sha256sum | cut -d' ' -f1
}
if [ "${1:-}" = "--check" ]; then
    want=$(stamp)
    have=$(cat "$out/myriad_web.wasm.sources" 2>/dev/null || true)
    if [ "$want" != "$have" ]; then
        echo "viewer/myriad_web.wasm is older than its sources: run crates/myriad-web/build.sh" >&2
        exit 1
    fi
    exit 0
fi
cargo build -p myriad-web --profile wasm --target wasm32-unknown-unknown
cp target/wasm32-unknown-unknown/wasm/myriad_web.wasm "$out/myriad_web.wasm"
stamp > "$out/myriad_web.wasm.sources"
echo "$out/myriad_web.wasm: $(wc -c < "$out/myriad_web.wasm") bytes"
