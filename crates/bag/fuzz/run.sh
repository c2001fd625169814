#!/usr/bin/env bash
# Run the unitac-bag fuzz targets (mcap, cdr, metadata) for SECONDS each (default 60) with
# cargo-fuzz on nightly, seeded from corpus/ (metadata.yaml and CDR files committed here; MCAP
# seeds are small bags written by the crate's writer, see below).
# Without cargo-fuzz or nightly, runs the CI smoke instead: the same entry functions over a
# seeded, mutated corpus in a normal test (crates/bag/tests/hostile.rs, fuzz_smoke_seeded_corpus).
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../../.." && pwd)"
SECONDS_EACH="${1:-60}"
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
  echo "cargo-fuzz on nightly not available (cargo install cargo-fuzz; rustup toolchain install nightly);" >&2
  echo "running the seeded smoke test instead" >&2
  cd "$ROOT" && exec cargo test -p unitac-bag --test hostile fuzz_smoke
fi
cd "$HERE"
# The fuzzers grow their corpus in work/ (ignored by git); the committed seeds stay as they are.
mkdir -p work/mcap work/cdr work/metadata
# MCAP seeds: small bags from the writer (none / zstd / lz4 chunks).
if ! ls work/mcap/*.mcap >/dev/null 2>&1; then
  (cd "$ROOT" && UNITAC_FUZZ_SEED_DIR="$HERE/work/mcap" cargo test -q -p unitac-bag --test hostile write_fuzz_seeds -- --ignored)
fi
cp -n corpus/cdr/* work/cdr/ && cp -n corpus/metadata/* work/metadata/
for t in mcap cdr metadata; do
  # A crash or out-of-memory input lands in artifacts/<target>/: copy it to regressions/ and
  # tests/hostile.rs::fuzz_regressions replays it in CI.
  # -timeout: one input may take 5 s (libFuzzer's default, 1200 s, hid quadratic YAML nesting);
  # tests/hostile.rs::fuzz_smoke_seeded_corpus uses the same limit.
  cargo +nightly fuzz run "$t" "work/$t" -- -max_total_time="$SECONDS_EACH" -timeout=5 \
    -rss_limit_mb=1024 -max_len=1048576 -print_final_stats=1
done
