#!/usr/bin/env bash
# Long fuzz run of the Structured Text lexer, parser, compiler and runtime, and of the
# differential arithmetic tests (property tests of crates/plc/tests/fuzz.rs and
# differential.rs with many cases, release build). Usage:
#   scripts/fuzz-plc.sh [CASES_PER_PROPERTY]   (default 50000; six properties)
set -euo pipefail
cd "$(dirname "$0")/.."
cases="${1:-50000}"
echo "fuzzing the PLC: $cases cases per property, 6 properties"
start=$(date +%s)
PLC_FUZZ_CASES="$cases" cargo test --release -p rtcnc-plc --test fuzz --test differential -- --test-threads 2
echo "done: $((cases * 6)) cases in $(( $(date +%s) - start )) s"
