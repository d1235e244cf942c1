#!/bin/sh
# Builds the Debian package with CPack into WORK, checks its name, its declared dependencies
# and contents, unpacks it with dpkg-deb -x (no root, nothing installed) and runs every
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
exec sh "$here/run_programs.sh" "$work/root/usr" "$@"
