#!/usr/bin/env bash
# Builds the Debian package from the debug build (scripts/deb.sh --debug) and checks it
# without installing it on this machine: its control fields and files, its unit file, and
# the binary extracted from it running a shipped machine from a folder outside the checkout.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)

deb=$(scripts/deb.sh --debug)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

fail() { echo "test-deb: $*" >&2; exit 1; }

# Outputs go to files before grep: with pipefail, `grep -q` quitting at its first match can
# end the writer with SIGPIPE and fail a check that matched.
[ "$(dpkg-deb --field "$deb" Package)" = rtcnc ] || fail "package name"
depends=$(dpkg-deb --field "$deb" Depends)
[[ "$depends" == *"libc6 (>= "* ]] || fail "Depends: $depends"
dpkg-deb --contents "$deb" | awk '{print $2 " " $6}' >"$tmp/contents"
for path in ./usr/bin/rtcnc ./lib/systemd/system/rtcnc.service \
    ./usr/share/rtcnc/configs/sim-mill.toml ./usr/share/rtcnc/configs/mill.st \
    ./usr/share/rtcnc/configs/sim-lathe.toml ./usr/share/rtcnc/examples/bracket.ngc \
    ./usr/share/rtcnc/examples/plc/mill.st ./usr/share/doc/rtcnc/LICENSE-MIT \
    ./usr/share/doc/rtcnc/README.md; do
  grep -q " $path\$" "$tmp/contents" || fail "$path missing"
done
grep -q "^root/root " "$tmp/contents" || fail "files not owned by root"
dpkg-deb --ctrl-tarfile "$deb" | tar -t >"$tmp/control-files"
grep -qx "./postinst" "$tmp/control-files" || fail "postinst missing"

dpkg-deb --extract "$deb" "$tmp/root"
# Every machine file of the checkout is in the package.
for f in configs/*.toml; do
  [ -f "$tmp/root/usr/share/rtcnc/$f" ] || fail "$f missing"
done
if command -v systemd-analyze >/dev/null; then
  # The unit parses (the rtcnc user is made by postinst, which does not run here).
  systemd-analyze verify "$tmp/root/lib/systemd/system/rtcnc.service" 2>&1 \
    | grep -v "is not executable\|User=rtcnc\|Group=rtcnc" \
    | grep -i "rtcnc.service" && fail "unit file"
fi

# The packaged binary, run from an empty folder: the default machine and the packaged
# machine file give the same report on the packaged example.
mkdir "$tmp/work"
cd "$tmp/work"
export XDG_DATA_HOME="$tmp/data"
bin="$tmp/root/usr/bin/rtcnc"
"$bin" machines >machines.txt || fail "rtcnc machines"
grep -q "^sim-mill .*(default)" machines.txt || fail "rtcnc machines: $(cat machines.txt)"
share="$tmp/root/usr/share/rtcnc"
# The two simulations run side by side (a debug build's minute each).
"$bin" sim "$share/examples/bracket.ngc" -q >built-in.txt &
built_in=$!
"$bin" sim "$share/examples/bracket.ngc" -q --machine "$share/configs/sim-mill.toml" >file.txt &
from_file=$!
wait "$built_in" || fail "sim with the default machine"
wait "$from_file" || fail "sim with the packaged machine file"
grep -q "faults      none" built-in.txt || fail "faults: $(cat built-in.txt)"
diff <(grep -v "^machine \|^simulated " built-in.txt) <(grep -v "^machine \|^simulated " file.txt) \
  || fail "the default machine and the packaged file differ"
cd "$repo"
echo "test-deb: $deb checked"
