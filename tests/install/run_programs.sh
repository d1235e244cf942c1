#!/bin/sh
# Runs every installed program's --help from an installed tree and checks that it starts (the
# run path finds the project's shared library) and prints its usage; then checks that
# lookup-sim looks for its presets in the tree's own share/lookup before any other folder.
# Usage: run_programs.sh PREFIX PROGRAM...
set -u
prefix=$(cd "$1" && pwd -P) || { echo "run_programs: no folder $1"; exit 1; }
shift
failed=0
for p in "$@"; do
    exe="$prefix/bin/$p"
    if [ ! -x "$exe" ]; then
        echo "FAIL $p: $exe is not installed"
        failed=1
        continue
    fi
    out=$("$exe" --help 2>&1)
    rc=$?
    case "$p" in
        lookup-bench) expected="benchmark_filter" ;;
        *) expected="$p" ;;
    esac
    if [ $rc -ne 0 ]; then
        echo "FAIL $p --help: exit $rc: $(echo "$out" | head -3)"
        failed=1
    elif ! echo "$out" | grep -q -- "$expected"; then
        echo "FAIL $p --help: output lacks '$expected': $(echo "$out" | head -3)"
        failed=1
    else
        echo "ok   $p --help"
    fi
done
if [ -x "$prefix/bin/lookup-sim" ]; then
    out=$("$prefix/bin/lookup-sim" --preset no-such-preset --out "$prefix/../no-such-out" 2>&1)
    first="tried $prefix/share/lookup/scenarios/no-such-preset.ini"
    if echo "$out" | grep -q -F -- "$first"; then
        echo "ok   lookup-sim looks in $prefix/share/lookup first"
    else
        echo "FAIL lookup-sim preset search does not start in $prefix/share/lookup: $out"
        failed=1
    fi
fi
exit $failed
