#!/usr/bin/env bash
# 12 simulated CSP drives and a DIO terminal at 1 kHz over a veth pair, in a network
# namespace: the master (rtcnc-ethercat) on one end, the simulator process on the other.
# Prints cycles, working-counter errors, the frames' round trip p50/p99/max, the master's
# CPU time per cycle and the cycle thread's wake-up latency, then cyclictest's over the
# same duration for comparison. Then the same bus under the whole kernel: `rtcnc run --idle`
# on configs/ethercat-sim-12.toml (without its in-process simulation, on the veth pair),
# the drives enabled, every task's CPU time and the fieldbus thread's lateness.
#
#   bench/ethercat.sh [MINUTES] [--debug]     # 10 minutes by default; e.g. 0.1 for 6 s
#
# --debug uses the test build (target/debug) instead of building optimised binaries.
set -euo pipefail
cd "$(dirname "$0")/.."
minutes="${1:-10}"
profile=release
[ "${2:-}" = "--debug" ] && profile=debug
scripts/setup.sh rt-tests
seconds=$(python3 -c "print(max(1, round(float('${minutes}') * 60)))")

if [ "$profile" = release ]; then
  cargo build --release -q -p rtcnc-ecat-slave-sim --bin ecat-slave-sim
  cargo build --release -q -p rtcnc-ethercat --example ethercat_bench
  cargo build --release -q -p rtcnc --bin rtcnc
else
  # The test build has all three. Built one package at a time, each would build its
  # dependencies again with that package's own features (serde, ethercrab, the kernel,
  # rtcnc: minutes from nothing).
  cargo test -q --workspace --locked --no-run
fi
rtcnc="target/${profile}/rtcnc"
sim="target/${profile}/ecat-slave-sim"
bench="target/${profile}/examples/ethercat_bench"
segment="$(mktemp)"
machine="$(mktemp --suffix .toml)"
trap 'rm -f "$segment" "$machine"' EXIT
# The 12-drive gantry on the veth pair: the devices on m0 instead of in the process.
sed -e '/^\[fieldbus.simulation\]/,/^$/d' -e 's/^interface = "ecat0"/interface = "m0"/' \
  configs/ethercat-sim-12.toml >"$machine"
# The DIO terminal's input 7 is the gantry's e-stop chain (normally closed): closed.
printf '[[slaves]]\nkind = "csp_drive"\ncount = 12\n[[slaves]]\nkind = "dio"\nterminal = { initial_inputs = 128 }\n' >"$segment"

# As root, a network namespace alone keeps the right to real-time scheduling; otherwise an
# unprivileged user namespace owns it (and SCHED_FIFO is refused: the figures say so).
if [ "$(id -u)" -eq 0 ]; then namespace=(unshare -n); else namespace=(unshare -Urn); fi
if ! "${namespace[@]}" true 2>/dev/null; then
  echo "skipped: ${namespace[*]} refused (network namespaces are needed for the veth pair)"
  exit 0
fi

echo "== rtcnc EtherCAT master, 12 drives + DIO over veth, 1 ms, ${seconds} s (${profile})"
"${namespace[@]}" bash -c '
  set -euo pipefail
  ip link add m0 type veth peer name s0
  ip link set m0 up
  ip link set s0 up
  mkfifo "$0.in"
  "$1" --interface s0 --config "$0" --priority 70 <"$0.in" >/dev/null &
  sim=$!
  exec 3>"$0.in"
  rm -f "$0.in"
  sleep 0.3
  "$2" --interface m0 --drives 12 --seconds "$3"
  echo quit >&3
  wait "$sim"
' "$segment" "$sim" "$bench" "$seconds"

echo "== rtcnc run --idle ${seconds} s, configs/ethercat-sim-12.toml on the veth pair (${profile})"
# `rtcnc run --idle` fails only when the machine did not start (the bus, the self-test or
# enabling the drives): that fails this script. A start spoiled by the loaded host alone
# (late cycles: frames not back in time, a following error, set-points run dry) is
# reported and tried again, at most three times; faults during the idle run are reported.
if ! "${namespace[@]}" bash -c '
  set -uo pipefail
  ip link add m0 type veth peer name s0
  ip link set m0 up
  ip link set s0 up
  mkfifo "$0.in"
  "$1" --interface s0 --config "$0" --priority 70 <"$0.in" >/dev/null &
  sim=$!
  exec 3>"$0.in"
  rm -f "$0.in"
  sleep 0.3
  for attempt in 1 2 3; do
    status=0
    output=$("$2" run --idle "$3" --machine "$4" 2>&1) || status=$?
    printf "%s\n" "$output" | grep -v "^\s*$"
    [ "$status" -eq 0 ] && break
    codes=$(printf "%s\n" "$output" | grep -o "\[kernel\.[a-z_]*\]" | sort -u)
    other=$(printf "%s\n" "$codes" |
      grep -v -E "^\[kernel\.(communication|following_error|setpoints_ran_dry|setpoints_lost)\]$")
    if [ -z "$codes" ] || [ -n "$other" ]; then break; fi
    echo "(start $attempt spoiled by late cycles on the loaded host: again)"
  done
  echo quit >&3
  wait "$sim"
  exit "$status"
' "$segment" "$sim" "$rtcnc" "$seconds" "$machine"; then
  echo "FAILED: rtcnc run did not start the machine on the EtherCAT bus"
  exit 1
fi

echo "== cyclictest, 1 ms, ${seconds} s (the machine's own wake-up latency)"
if command -v cyclictest >/dev/null 2>&1; then
  cyclictest -m -p 80 -i 1000 -t 1 -D "${seconds}s" -q 2>&1 | tail -n 2 || true
else
  echo "cyclictest not installed (scripts/setup.sh rt-tests)"
fi
