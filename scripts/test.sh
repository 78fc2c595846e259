#!/usr/bin/env bash
# Sets up and runs every test of rtcnc: formatting, lints, unit, integration and
# property tests of every crate, and a few seconds of each fuzz target. CI (.ci/run) calls
# exactly this.
set -euo pipefail
cd "$(dirname "$0")/.."
# Each phase prints when it starts (seconds since the start), so a slow run shows where
# its time went.
phase() { echo "== $* [${SECONDS} s]"; }
# openssl makes the TLS test's certificate; binutils' objdump reads the glibc version the
# Debian package depends on; Chromium runs the web HMI's end-to-end tests; mosquitto is the
# MQTT broker of the publisher's tests.
scripts/setup.sh openssl binutils chromium-headless-shell mosquitto

# Property tests draw from a fixed seed here, so a commit passes or fails the same way every
# time; the long randomised runs live in scripts/ and bench/ and pick fresh seeds.
export PROPTEST_RNG_SEED="${PROPTEST_RNG_SEED:-20261122}"

phase "cargo fmt --check"
cargo fmt --all -- --check
(cd fuzz && cargo fmt -- --check)
phase "every integration test file is built (scripts/check-test-files.py)"
scripts/check-test-files.py
phase "cargo clippy -D warnings"
cargo clippy --workspace --all-targets --locked -- -D warnings
# The motion crate's debugging tools build only with its diagnostics feature.
cargo clippy -p rtcnc-motion --all-targets --features diagnostics --locked -- -D warnings
phase "cargo doc, warnings denied"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked
phase "cargo test: build"
cargo test --workspace --locked --no-run
phase "cargo test: run"
cargo test --workspace --locked
phase "EtherCAT over veth, 3 s (bench/ethercat.sh 0.05 --debug)"
bench/ethercat.sh 0.05 --debug

phase "Python client (sdk/python) against a real rtcnc serve"
scripts/setup-python.sh
(cd sdk/python && ../../target/python-venv/bin/python -m pytest -q -p no:cacheprovider tests)

phase "Debian package (scripts/test-deb.sh: built from the debug build, checked unpacked)"
scripts/test-deb.sh

phase "fuzz targets, a short run (scripts/fuzz.sh; the dedicated run is in docs/fuzzing.md)"
scripts/fuzz.sh --dev --scratch --seconds "${FUZZ_SECONDS:-5}"

phase "web HMI: types, unit tests, the committed bundle (scripts/hmi.sh check)"
scripts/hmi.sh check
phase "web HMI in headless Chromium against a real rtcnc serve (scripts/hmi.sh e2e)"
scripts/hmi.sh e2e
echo "== all passed [${SECONDS} s]"
