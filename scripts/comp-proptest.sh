#!/usr/bin/env bash
# scripts/comp-proptest.sh [CASES] - long run of the cutter compensation stage's property
# tests (never panics on any command stream, holds at most its capacity, transparent without
# G41/G42); the normal test run does a few hundred cases. Default 100 000 cases, release
# build (a few minutes on 2 cores).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PROPTEST_CASES=${1:-100000} cargo test --release -q --manifest-path "$ROOT/Cargo.toml" \
  -p rtcnc-gcode --test suite -- compensation_stage::stage_never_panics \
  compensation_stage::stage_is_transparent
