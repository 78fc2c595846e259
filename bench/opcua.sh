#!/usr/bin/env bash
# The OPC UA server's figures on this machine: update rate of a subscription (sampling 1 ms
# and 10 ms), latency of a change to an OPC UA client (p50, p99), and 50 OPC UA clients
# subscribed while a program runs at 1 kHz for 60 s beside the same run without them
# (deadline misses, worst wake-up).
# About 3 minutes. OPCUA_BENCH_SECONDS, OPCUA_BENCH_CLIENTS, OPCUA_BENCH_PUBLISH_MS change it;
# RTCNC_BIN names another build (default: the release build, made here).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/setup-python.sh
if [ -z "${RTCNC_BIN:-}" ]; then
  cargo build --release -p rtcnc --locked
  export RTCNC_BIN=target/release/rtcnc
fi
target/python-venv/bin/python bench/opcua_bench.py
