#!/usr/bin/env bash
# Run the unitac-driver fuzz targets (mjpeg: the sensor stream's MJPEG decode on every path;
# still: PNG / JPEG image files) for SECONDS each (default 60) with cargo-fuzz on nightly, seeded
# from corpus/ (tiny images written by tests/fuzz_smoke.rs::write_fuzz_seeds, committed here).
# Without cargo-fuzz or nightly, runs the CI smoke instead: the same entry functions over the
# seeded, mutated corpus in a normal test (crates/driver/tests/fuzz_smoke.rs).
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../../.." && pwd)"
SECONDS_EACH="${1:-60}"
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
  echo "cargo-fuzz on nightly not available (cargo install cargo-fuzz; rustup toolchain install nightly);" >&2
  echo "running the seeded smoke test instead" >&2
  cd "$ROOT" && exec cargo test -p unitac-driver --test fuzz_smoke
fi
cd "$HERE"
# The fuzzers grow their corpus in work/ (ignored by git); the committed seeds stay as they are.
for t in mjpeg still; do
  mkdir -p "work/$t"
  cp -n corpus/"$t"/* "work/$t/"
done
for t in mjpeg still; do
  # A crash or out-of-memory input lands in artifacts/<target>/: copy it to regressions/ and
  # tests/fuzz_smoke.rs::fuzz_regressions replays it in CI.
  # -timeout: one input may take 5 s; tests/fuzz_smoke.rs uses the same limit.
  cargo +nightly fuzz run "$t" "work/$t" -- -max_total_time="$SECONDS_EACH" -timeout=5 \
    -rss_limit_mb=1024 -max_len=262144 -print_final_stats=1
done
