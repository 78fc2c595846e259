#!/usr/bin/env bash
# Coverage-guided fuzzing of rtcnc (cargo fuzz, libFuzzer) on every target of fuzz/:
#   scripts/fuzz.sh [--runs N | --seconds S] [--workers W] [--no-trace-compares] [--dev] [--scratch] [TARGET...]
# --runs N      N inputs per target (default 10000000: the dedicated run of docs/fuzzing.md)
# --seconds S   S seconds per target instead (the short run of scripts/test.sh)
# --workers W   W processes per target on the same corpus (N/W inputs each; default 1)
# --no-trace-compares  build without libFuzzer's comparison tracing, in fuzz/target-ntc
#               (the kernel target's operation decoder gains little from it; it is about
#               half of that target's time)
# --dev         build without optimisations (cargo fuzz build --dev): a few times faster to
#               build from nothing (the optimised build is one codegen unit per crate of the
#               whole dependency tree), several times slower per input; for short runs
# --scratch     grow a scratch corpus from the seeds, removed afterwards, instead of
#               fuzz/corpus/TARGET (a short run then takes the same time wherever it runs:
#               libFuzzer reads a whole corpus before it looks at the clock)
# Targets default to all (`cargo fuzz list`). The build is the stable toolchain's with
# libFuzzer's coverage instrumentation, overflow checks and debug assertions on (no
# sanitizer: safe Rust needs none; FUZZ_SANITIZER=address uses nightly's ASan when present).
# The inputs kept in fuzz/defects/TARGET run once first (regression inputs).
# Corpora grow in fuzz/corpus/TARGET (not committed), starting from fuzz/seeds/TARGET;
# crashes, hangs (> 10 s) and out-of-memory inputs land in fuzz/artifacts/TARGET and make
# the script fail. Prints one line of figures per target.
set -euo pipefail
cd "$(dirname "$0")/.."

runs=10000000
seconds=""
workers=1
trace_compares=()
build_mode=-O
profile_dir=release
scratch=""
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --seconds) seconds="$2"; shift 2 ;;
    --workers) workers="$2"; shift 2 ;;
    --no-trace-compares) trace_compares=(--no-trace-compares --target-dir target-ntc); shift ;;
    --dev) build_mode=--dev; profile_dir=debug; shift ;;
    --scratch) scratch=$(mktemp -d); trap 'rm -rf "$scratch"' EXIT; shift ;;
    -h|--help) sed -n '2,22p' "$0"; exit 0 ;;
    *) targets+=("$1"); shift ;;
  esac
done

command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz --locked --version 0.13.2
sanitizer="${FUZZ_SANITIZER:-none}"
toolchain=()
[ "$sanitizer" != none ] && toolchain=(+nightly)

cd fuzz
[ ${#targets[@]} -gt 0 ] || mapfile -t targets < <(cargo "${toolchain[@]}" fuzz list)
cargo "${toolchain[@]}" fuzz build -s "$sanitizer" "$build_mode" "${trace_compares[@]}" >/dev/null 2>build.log \
  || { cat build.log; exit 1; }
triple=$(rustc -vV | sed -n 's/^host: //p')
target_dir=target
[ ${#trace_compares[@]} -gt 0 ] && target_dir=target-ntc

failed=0
printf '%-14s %12s %8s %10s %6s %s\n' target inputs seconds inputs/s cov crashes
for t in "${targets[@]}"; do
  mkdir -p "corpus/$t" "artifacts/$t"
  grow="corpus/$t"
  [ -n "$scratch" ] && { grow="$scratch/$t"; mkdir -p "$grow"; }
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
  # Every input kept in fuzz/defects/TARGET once showed a defect (now fixed): each runs
  # once, and any that fails again fails the script.
  if compgen -G "defects/$t/*" >/dev/null; then
    if ! "$target_dir/$triple/$profile_dir/$t" defects/"$t"/* >"corpus/$t.defects.log" 2>&1; then
      failed=1
      echo "$t: a kept defect input fails again (fuzz/corpus/$t.defects.log)"
      grep -hE 'panicked|Running:' "corpus/$t.defects.log" | tail -3 || true
    fi
  fi
  start=$(date +%s)
  # The binary built above, run directly: editing the sources meanwhile changes nothing.
  # Each worker logs to corpus/TARGET.log (the first) or corpus/TARGET.K.log and shares
  # the corpus folder (libFuzzer reloads it now and then).
  pids=()
  logs=()
  for ((k = 0; k < workers; k++)); do
    log="corpus/$t.log"
    [ "$k" -gt 0 ] && log="corpus/$t.$k.log"
    logs+=("$log")
    [ -z "$seconds" ] && limit=(-runs=$(( (runs + workers - 1) / workers )))
    "$target_dir/$triple/$profile_dir/$t" -artifact_prefix="artifacts/$t/" \
      "${limit[@]}" "${dict[@]}" -timeout=10 -rss_limit_mb=2048 "${length[@]}" \
      -print_final_stats=1 "$grow" "${seeds[@]}" >"$log" 2>&1 &
    pids+=($!)
  done
  status=0
  for pid in "${pids[@]}"; do wait "$pid" || status=$?; done
  elapsed=$(( $(date +%s) - start ))
  # libFuzzer's final statistics (also printed when it stops at a crash), summed.
  inputs=0
  cov=""
  for log in "${logs[@]}"; do
    n=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    inputs=$(( inputs + ${n:-0} ))
    c=$( (grep -oE 'cov: [0-9]+' "$log" || true) | tail -1 | cut -d' ' -f2)
    [ -n "$c" ] && { [ -z "$cov" ] || [ "$c" -gt "$cov" ]; } && cov=$c
  done
  after=$(find "artifacts/$t" -type f | wc -l)
  crashes=$(( after - before ))
  printf '%-14s %12s %8s %10s %6s %s\n' "$t" "$inputs" "$elapsed" \
    "$(( inputs / (elapsed > 0 ? elapsed : 1) ))" "${cov:-?}" "$crashes"
  if [ "$status" -ne 0 ] || [ "$crashes" -gt 0 ]; then
    failed=1
    grep -hE 'panicked|ERROR: libFuzzer|SUMMARY' "${logs[@]}" | head -5 || true
    echo "  logs: ${logs[*]/#/fuzz/}; inputs: fuzz/artifacts/$t/"
  fi
done
exit "$failed"
