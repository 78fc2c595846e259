#!/usr/bin/env bash
# The API's figures on this machine: urgent latency in servo periods (p50, p99, max), REST
# status round trip, 100 WebSocket clients at 50 Hz for 60 s while a program runs at 1 kHz
# beside the same run without clients (deadline misses, worst wake-up latency), RSS of the
# machine and API processes. About 2.5 minutes. API_BENCH_SECONDS shortens the runs.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/setup-python.sh
cargo build --release -p rtcnc --locked
RTCNC_BIN=target/release/rtcnc target/python-venv/bin/python bench/api_bench.py
