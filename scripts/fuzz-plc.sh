#!/usr/bin/env bash
# Long fuzz run of the Structured Text lexer, parser, compiler and runtime (property tests
# of crates/plc/tests/fuzz.rs with many cases, release build). Usage:
#   scripts/fuzz-plc.sh [CASES_PER_PROPERTY]   (default 50000; four properties)
set -euo pipefail
cd "$(dirname "$0")/.."
cases="${1:-50000}"
echo "fuzzing the PLC front end: $cases cases per property, 4 properties"
start=$(date +%s)
PLC_FUZZ_CASES="$cases" cargo test --release -p rtcnc-plc --test fuzz -- --test-threads 2
echo "done: $((cases * 4)) cases in $(( $(date +%s) - start )) s"
