#!/usr/bin/env bash
# scripts/fuzz-gcode.sh [CASES] - long property run of the G-code interpreter: CASES
# generated programs (default 1 000 000) for each of the two properties in
# crates/gcode/tests/fuzz.rs (token programs, raw bytes), release build. The normal test
# command runs the same properties with a few hundred cases.
set -euo pipefail
cd "$(dirname "$0")/.."
CASES=${1:-1000000}
echo "fuzzing rtcnc-gcode with $CASES cases per property"
start=$(date +%s)
FUZZ_CASES=$CASES cargo test --release -q -p rtcnc-gcode --test fuzz -- --test-threads=1
echo "done: $((2 * CASES)) inputs without a panic in $(( $(date +%s) - start )) s"
