#!/usr/bin/env bash
# Builds the Debian package of rtcnc with dpkg-deb: the `rtcnc` binary, the shipped machine
# files and examples under /usr/share/rtcnc, the README, docs and licences under
# /usr/share/doc/rtcnc, and the systemd unit of `rtcnc serve` (installed, not enabled), with
# a system user `rtcnc` for it. Prints the package's path.
#   scripts/deb.sh            release build
#   scripts/deb.sh --debug    the debug build (what the tests package: quicker to build)
set -euo pipefail
cd "$(dirname "$0")/.."

profile=release
[ "${1:-}" = "--debug" ] && profile=debug
if [ "$profile" = release ]; then
  cargo build -p rtcnc --locked --release
else
  # The test build's binary: `cargo build -p rtcnc` would build rtcnc's dependencies again
  # with its own features.
  cargo test -q --workspace --locked --no-run
fi

version=$(sed -n 's/^version = "\(.*\)"/\1/p' Cargo.toml | head -1)
arch=$(dpkg --print-architecture)
out=target/debian
root="$out/rtcnc_${version}_${arch}"
rm -rf "$root"
install -D -m 0755 "target/$profile/rtcnc" "$root/usr/bin/rtcnc"
strip "$root/usr/bin/rtcnc"
install -d "$root/usr/share/rtcnc/configs" "$root/usr/share/rtcnc/examples"
cp configs/*.toml configs/*.tbl "$root/usr/share/rtcnc/configs/"
# The machine files as `rtcnc machines --write` gives them: the PLC programs beside the mills.
"target/$profile/rtcnc" machines --write sim-mill "$root/usr/share/rtcnc/configs" >/dev/null
"target/$profile/rtcnc" machines --write sim-mill-carousel "$root/usr/share/rtcnc/configs" >/dev/null
cp -r examples/*.ngc examples/gcode examples/plc "$root/usr/share/rtcnc/examples/"
install -d "$root/usr/share/doc/rtcnc"
cp README.md CHANGELOG.md LICENSE-MIT LICENSE-APACHE "$root/usr/share/doc/rtcnc/"
cp -r docs "$root/usr/share/doc/rtcnc/"
install -D -m 0644 packaging/debian/rtcnc.service "$root/lib/systemd/system/rtcnc.service"
install -d "$root/DEBIAN"
install -m 0755 packaging/debian/postinst packaging/debian/postrm "$root/DEBIAN/"
# The newest glibc symbol version the binary needs.
glibc=$(objdump -T "$root/usr/bin/rtcnc" | grep -o 'GLIBC_[0-9.]*' | sed 's/GLIBC_//' | sort -V | tail -1)
size=$(du -sk --exclude=DEBIAN "$root" | cut -f1)
cat >"$root/DEBIAN/control" <<CONTROL
Package: rtcnc
Version: $version
Architecture: $arch
Maintainer: rtcnc developers <rtcnc@localhost>
Installed-Size: $size
Depends: libc6 (>= $glibc), libgcc-s1, adduser
Section: misc
Priority: optional
Description: open software CNC and motion controller
 G-code in, coordinated jerk-limited motion out, on a real-time executive, with a
 Structured Text soft PLC, simulated drives out of the box and EtherCAT drives for
 real machines. Includes the simulated machines (rtcnc machines), the example
 programs and a systemd unit for the machine service (rtcnc serve).
CONTROL
# Folders 0755, files 0644 unless executable, owned by root in the package.
find "$root" -type d -exec chmod 0755 {} +
find "$root/usr/share" -type f -exec chmod 0644 {} +
# The debug build's package is the tests' (their binary is a 67 MB unoptimised one): gzip
# instead of xz, about 3 s instead of a minute.
compression=()
[ "$profile" = debug ] && compression=(-Zgzip)
dpkg-deb --build --root-owner-group "${compression[@]}" "$root" "$out/" >/dev/null
rm -rf "$root"
echo "$out/rtcnc_${version}_${arch}.deb"
