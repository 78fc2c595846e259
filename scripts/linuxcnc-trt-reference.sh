#!/usr/bin/env bash
# scripts/linuxcnc-trt-reference.sh [ac|bc|head] - the reference joint positions of the TCP
# tests (crates/kernel/tests/tool_centre_point.rs, crates/motion/tests/table_kinematics.rs,
# crates/kernel/tests/tool_centre_point_head.rs)
# from LinuxCNC 2.9 itself: runs the tests' program (TCP moves, a dwell after each) in
# LinuxCNC's simulator, headless, with xyzac-trt-kins (y-offset 20, z-offset 10, rot point
# at the origin) or xyzbc-trt-kins (x-offset -15, z-offset 10, rot point (5, -3, -40)),
# tool-offset from motion.tooloffset.z (T1, 50 mm), or 5axiskins (head: pivot-length 100
# plus motion.tooloffset.z, W a joint that stays 0), a perfect servo loop, and prints the
# joint positions (joint.N.pos-cmd, nine decimals) wherever the joints stood for 100
# periods: at the start, then at each dwell.
# Needs LinuxCNC 2.9 (Debian linuxcnc-uspace) and the peer folder's headless display
# program ($RTCNC_PEERS or ../shared/peers next to the repository, linuxcnc/sim/).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
KIND=${1:-ac}
if [ -z "${RTCNC_PEERS:-}" ]; then
  for d in "$ROOT/../shared/peers" "$ROOT/../../shared/peers"; do
    [ -d "$d" ] && RTCNC_PEERS=$d && break
  done
fi
HEADLESS=${RTCNC_PEERS:-/nonexistent}/linuxcnc/sim/headless_run.py
if [ ! -f "$HEADLESS" ] || ! command -v linuxcnc >/dev/null; then
  echo "needs linuxcnc and $HEADLESS; absent here" >&2
  exit 2
fi
# One LinuxCNC at a time on a machine (the peer scripts take the same lock).
exec 9>/tmp/lcncsim.flock
flock -w 900 9 || { echo "could not get /tmp/lcncsim.flock" >&2; exit 3; }
if [ -e /tmp/linuxcnc.lock ]; then
  echo "another LinuxCNC is running (/tmp/linuxcnc.lock)" >&2
  exit 3
fi
case $KIND in
  ac) KINS=xyzac-trt-kins; COORDS=XYZAC; TILT=A; TURNS=(45 135 225 315)
      PINS="setp $KINS.y-offset 20
setp $KINS.z-offset 10" ;;
  bc) KINS=xyzbc-trt-kins; COORDS=XYZBC; TILT=B; TURNS=(-211 -121 -31 59)
      PINS="setp $KINS.x-offset -15
setp $KINS.z-offset 10
setp $KINS.x-rot-point 5
setp $KINS.y-rot-point -3
setp $KINS.z-rot-point -40" ;;
  head) KINS=5axiskins; COORDS=XYZBCW; TILT=B; TURNS=(45 135 225 315)
      PINS="loadrt sum2 names=pivot
setp pivot.in1 100
net tooloff motion.tooloffset.z => pivot.in0
net pivotlen pivot.out => $KINS.pivot-length
addf pivot servo-thread" ;;
  *) echo "usage: $0 [ac|bc|head]" >&2; exit 2 ;;
esac
TOOLNET="net tooloff motion.tooloffset.z => $KINS.tool-offset"
JOINTS=5
[ "$KIND" = head ] && TOOLNET="" && JOINTS=6
ANGLE=-30; [ "$KIND" = bc ] && ANGLE=28; [ "$KIND" = head ] && ANGLE=30
W=$(mktemp -d /tmp/rtcnc-trt.XXXXXX)
trap 'rm -rf "$W"' EXIT
chmod 755 "$W"; mkdir -m 1777 "$W/fifo" "$W/out"
cat > "$W/prog.ngc" <<EOF
G21 G90 G94 G61
T1 M6
G43 H1
G0 X0 Y0 Z80 ${TILT}0 C0
G4 P0.3
G1 X20 Y0 Z5 F1200
G4 P0.3
G1 ${TILT}${ANGLE} C${TURNS[0]} F1800
G4 P0.3
G1 Y20 C${TURNS[1]} F600
G4 P0.3
G1 X-20 C${TURNS[2]}
G4 P0.3
G1 Y-20 C${TURNS[3]}
G4 P0.3
G0 Z40
G4 P0.3
M2
EOF
printf 'T1 P1 D6.0 Z+50.0\n' > "$W/sim.tbl"
printf '5220\t1.000000\n' > "$W/sim.var"
cat > "$W/sim.hal" <<EOF
loadrt [KINS]KINEMATICS
loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS
addf motion-command-handler servo-thread
addf motion-controller servo-thread
$PINS
$TOOLNET
net estop-loop iocontrol.0.user-enable-out iocontrol.0.emc-enable-in
net tool-prep-loop iocontrol.0.tool-prepare iocontrol.0.tool-prepared
net tool-change-loop iocontrol.0.tool-change iocontrol.0.tool-changed
loadrt scale names=s0,s1,s2,s3,s4
loadrt sampler cfg=ffffff depth=[SIMRUN]FIFO_DEPTH
setp sampler.0.enable 0
loadrt conv_s32_float names=conv_line
net tpline motion.program-line => conv_line.in
net tplinef conv_line.out => sampler.0.pin.5
EOF
[ "$JOINTS" = 6 ] && echo "net fb5 joint.5.motor-pos-cmd => joint.5.motor-pos-fb" >> "$W/sim.hal"
for j in 0 1 2 3 4; do
  cat >> "$W/sim.hal" <<EOF
net fb$j joint.$j.motor-pos-cmd => joint.$j.motor-pos-fb
setp s$j.gain 1000.0
net c$j joint.$j.pos-cmd => s$j.in
net u$j s$j.out => sampler.0.pin.$j
addf s$j servo-thread
EOF
done
printf 'addf conv_line servo-thread\naddf sampler.0 servo-thread\n' >> "$W/sim.hal"
cat > "$W/sim.ini" <<EOF
[EMC]
VERSION = 1.1
MACHINE = rtcnc-trt-reference
[DISPLAY]
DISPLAY = $HEADLESS
CYCLE_TIME = 0.100
[SIMRUN]
PROGRAM = $W/prog.ngc
OUTDIR = $W/out
TIMEOUT = 120
FIFO_DEPTH = 65536
[TASK]
TASK = milltask
CYCLE_TIME = 0.001
[RS274NGC]
PARAMETER_FILE = sim.var
[EMCMOT]
EMCMOT = motmod
COMM_TIMEOUT = 1.0
SERVO_PERIOD = 1000000
[EMCIO]
EMCIO = io
CYCLE_TIME = 0.100
TOOL_TABLE = sim.tbl
[HAL]
HALFILE = sim.hal
[TRAJ]
COORDINATES = $COORDS
LINEAR_UNITS = mm
ANGULAR_UNITS = degree
DEFAULT_LINEAR_VELOCITY = 50
MAX_LINEAR_VELOCITY = 100
DEFAULT_LINEAR_ACCELERATION = 500
MAX_LINEAR_ACCELERATION = 1000
[KINS]
KINEMATICS = $KINS
JOINTS = $JOINTS
EOF
AXES="X Y Z $TILT C"; [ "$JOINTS" = 6 ] && AXES="$AXES W"
for ax in $AXES; do
  printf '[AXIS_%s]\nMAX_VELOCITY = 100\nMAX_ACCELERATION = 1000\nMIN_LIMIT = -100000\nMAX_LIMIT = 100000\n' "$ax" >> "$W/sim.ini"
done
for j in $(seq 0 $((JOINTS - 1))); do
  T=LINEAR; [ $j -ge 3 ] && [ $j -le 4 ] && T=ANGULAR
  printf '[JOINT_%s]\nTYPE = %s\nHOME = 0.0\nMAX_VELOCITY = 100\nMAX_ACCELERATION = 1000\nMIN_LIMIT = -100000\nMAX_LIMIT = 100000\nFERROR = 1000\nMIN_FERROR = 1000\nHOME_SEARCH_VEL = 0\nHOME_LATCH_VEL = 0\nHOME_SEQUENCE = 0\n' "$j" "$T" >> "$W/sim.ini"
done
# rtapi_app refuses to run with real uid 0 unless given a fallback uid and a FIFO path
# that uid can bind.
export RTAPI_UID=$(id -u nobody) RTAPI_FIFO_PATH="$W/fifo/rtapi_fifo"
unset DISPLAY
(cd "$W" && HOME="$W" timeout 300 linuxcnc -r "$W/sim.ini" > "$W/out/linuxcnc.log" 2>&1 </dev/null) || true
if ! grep -q '^result=OK' "$W/out/run_status.txt" 2>/dev/null; then
  echo "LinuxCNC run failed:" >&2
  cat "$W/out/run_status.txt" "$W/out/linuxcnc.log" >&2 2>/dev/null || true
  exit 1
fi
python3 - "$W/out/samples.raw" <<'EOF'
import sys
rows = [list(map(float, l.split())) for l in open(sys.argv[1])]
still = 0
for i in range(1, len(rows)):
    same = all(abs(rows[i][k] - rows[i - 1][k]) < 1e-9 for k in range(1, 6))
    still = still + 1 if same else 0
    if still == 100:
        print('[%s],' % ', '.join('%.9f' % (v / 1000) for v in rows[i][1:6]))
EOF
