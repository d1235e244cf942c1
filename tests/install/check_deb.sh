#!/bin/sh
# Builds the Debian package with CPack into WORK, checks its name, its declared dependencies
# and contents (no test fixture library; the systemd unit, sensors.ini, docs), unpacks it with dpkg-deb -x (no root, nothing installed) and runs every
# program's --help from the unpacked /usr.
# Usage: check_deb.sh CPACK BUILD_DIR WORK DEB_FILE_NAME PROGRAM...
set -u
cpack=$1 build=$2 work=$3 deb_name=$4
shift 4
here=$(dirname "$0")
rm -rf "$work" && mkdir -p "$work" || exit 1
if ! "$cpack" -G DEB -B "$work" --config "$build/CPackConfig.cmake" >"$work/cpack.log" 2>&1; then
    echo "FAIL cpack -G DEB:"; tail -20 "$work/cpack.log"; exit 1
fi
deb="$work/$deb_name"
[ -f "$deb" ] || { echo "FAIL no $deb_name; made: $(ls "$work")"; exit 1; }
depends=$(dpkg-deb -f "$deb" Depends)
echo "package $deb_name: $(stat -c %s "$deb") bytes; Depends: $depends"
for lib in libc6 libmrpt-obs libopencv-core; do
    if ! echo "$depends" | grep -q "$lib"; then
        echo "FAIL Depends lacks $lib (dpkg-shlibdeps did not run?)"; exit 1
    fi
done
if dpkg-deb -c "$deb" | grep -q -e refine_testing -e 'lookup/refine/testing'; then
    echo "FAIL the test fixture library is in the package"; exit 1
fi
dpkg-deb -x "$deb" "$work/root" || { echo "FAIL dpkg-deb -x"; exit 1; }
unit="$work/root/usr/share/lookup/systemd/lookup-localize.service"
for f in "$unit" "$work/root/usr/share/lookup/sensors/sensors.ini" \
         "$work/root/usr/share/doc/lookup/vehicle.md"; do
    [ -f "$f" ] || { echo "FAIL not in the package: ${f#$work/root}"; exit 1; }
done
# The unit's syntax, where systemd's checker is installed (not a build dependency).
if command -v systemd-analyze >/dev/null 2>&1; then
    systemd-analyze verify "$unit" || { echo "FAIL systemd-analyze verify $unit"; exit 1; }
    echo "ok   systemd-analyze verify lookup-localize.service"
fi
exec sh "$here/run_programs.sh" "$work/root/usr" "$@"
