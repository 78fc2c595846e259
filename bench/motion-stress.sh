#!/usr/bin/env bash
# Long randomised checks of the path planner (not in CI): random move lists through the
# planner, without and with on-line changes, every set-point's finite differences against
# every axis's v, a, j limit.
#   bench/motion-stress.sh [PROGRAMS_PER_SEED] [SEEDS]
# Prints, per seed, how many programs exceeded a limit and the first failing programs in the
# format of `cargo run -p rtcnc-motion --features diagnostics --example debug_line spec` (SPEC="x y z F mode P; ...").
# Then the proptest of tests/random.rs with more cases, and 10^6 mm of path (examples/long_paths.rs).
set -euo pipefail
cd "$(dirname "$0")/.."
n="${1:-500}"
seeds="${2:-1 2 3 4 5 6 7 8 9 10 11 12 13 14}"
cargo build -q --release -p rtcnc-motion --example stress
for s in $seeds; do
  echo "== seed $s"
  target/release/examples/stress "$n" "$s"
done
# The same seeds with an override, a hold and resume and (one program in ten) a quick stop
# at random periods.
for s in $seeds; do
  echo "== seed $s, on-line changes"
  STRESS_ONLINE=1 target/release/examples/stress "$n" "$s"
done
echo "== tests/random.rs with 512 cases"
PROPTEST_CASES=512 cargo test -q --release -p rtcnc-motion --test suite -- random::
echo "== tests/online_changes.rs and tests/splines_random.rs (release sizes)"
cargo test -q --release -p rtcnc-motion --test suite -- online_changes:: splines_random::
echo "== 10^6 mm of path at the benchmark machine's limits"
cargo run -q --release -p rtcnc-motion --example long_paths -- 1e6
