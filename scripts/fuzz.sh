#!/usr/bin/env bash
# Coverage-guided fuzzing of rtcnc (cargo fuzz, libFuzzer) on every target of fuzz/:
#   scripts/fuzz.sh [--runs N | --seconds S] [TARGET...]
# --runs N      N inputs per target (default 10000000: the dedicated run of docs/fuzzing.md)
# --seconds S   S seconds per target instead (the short run of scripts/test.sh)
# Targets default to all (`cargo fuzz list`). The build is the stable toolchain's with
# libFuzzer's coverage instrumentation, overflow checks and debug assertions on (no
# sanitizer: safe Rust needs none; FUZZ_SANITIZER=address uses nightly's ASan when present).
# Corpora grow in fuzz/corpus/TARGET (not committed), starting from fuzz/seeds/TARGET;
# crashes, hangs (> 10 s) and out-of-memory inputs land in fuzz/artifacts/TARGET and make
# the script fail. Prints one line of figures per target.
set -euo pipefail
cd "$(dirname "$0")/.."

runs=10000000
seconds=""
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --seconds) seconds="$2"; shift 2 ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) targets+=("$1"); shift ;;
  esac
done

command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz --locked --version 0.13.2
sanitizer="${FUZZ_SANITIZER:-none}"
toolchain=()
[ "$sanitizer" != none ] && toolchain=(+nightly)

cd fuzz
[ ${#targets[@]} -gt 0 ] || mapfile -t targets < <(cargo "${toolchain[@]}" fuzz list)
cargo "${toolchain[@]}" fuzz build -s "$sanitizer" -O >/dev/null 2>build.log || { cat build.log; exit 1; }
triple=$(rustc -vV | sed -n 's/^host: //p')

failed=0
printf '%-14s %12s %8s %10s %6s %s\n' target inputs seconds inputs/s cov crashes
for t in "${targets[@]}"; do
  mkdir -p "corpus/$t" "artifacts/$t"
  before=$(find "artifacts/$t" -type f | wc -l)
  limit=(-runs="$runs")
  [ -n "$seconds" ] && limit=(-max_total_time="$seconds")
  dict=()
  [ -f "dict/$t.dict" ] && dict=(-dict="dict/$t.dict")
  seeds=()
  [ -d "seeds/$t" ] && seeds=("seeds/$t")
  # The kernel target's inputs are operation sequences: libFuzzer's slow growth of input
  # lengths kept them at a few operations; long sequences from the start, up to the
  # length that fills its machine time.
  length=(-max_len=8192)
  [ "$t" = kernel ] && length=(-max_len=2048 -len_control=0)
  log="corpus/$t.log"
  start=$(date +%s)
  set +e
  # The binary built above, run directly: editing the sources meanwhile changes nothing.
  "target/$triple/release/$t" -artifact_prefix="artifacts/$t/" \
    "${limit[@]}" "${dict[@]}" -timeout=10 -rss_limit_mb=2048 "${length[@]}" \
    -print_final_stats=1 "corpus/$t" "${seeds[@]}" >"$log" 2>&1
  status=$?
  set -e
  elapsed=$(( $(date +%s) - start ))
  # libFuzzer's final statistics (also printed when it stops at a crash).
  inputs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  cov=$( (grep -oE 'cov: [0-9]+' "$log" || true) | tail -1 | cut -d' ' -f2)
  after=$(find "artifacts/$t" -type f | wc -l)
  crashes=$(( after - before ))
  inputs=${inputs:-0}
  printf '%-14s %12s %8s %10s %6s %s\n' "$t" "$inputs" "$elapsed" \
    "$(( inputs / (elapsed > 0 ? elapsed : 1) ))" "${cov:-?}" "$crashes"
  if [ "$status" -ne 0 ] || [ "$crashes" -gt 0 ]; then
    failed=1
    grep -E 'panicked|ERROR: libFuzzer|SUMMARY' "$log" | head -5 || true
    echo "  log: fuzz/$log; inputs: fuzz/artifacts/$t/"
  fi
done
exit "$failed"
