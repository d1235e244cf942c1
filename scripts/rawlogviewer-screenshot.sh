#!/usr/bin/env bash
# Screenshot of RawLogViewer showing a rawlog (with LookUP's plug-in loaded), under Xvfb.
# Usage: bash scripts/rawlogviewer-screenshot.sh RAWLOG OUT.png [ENTRY_INDEX] [PLUGIN.so]
# Needs xvfb, xdotool, imagemagick (apt-get install xvfb xdotool imagemagick x11-utils).
# RawLogViewer is started from the rawlog's folder with a relative name: MRPT 2.5.8 does not
# find external images for an absolute rawlog path (see DESIGN.md).
set -euo pipefail
RAWLOG=$(realpath "$1"); OUT=$(realpath -m "$2"); ENTRY=${3:-0}
PLUGIN=$(realpath "${4:-$(dirname "$0")/../build/lib/liblookup_obs.so}")
export DISPLAY=:${LOOKUP_XVFB_DISPLAY:-97}
Xvfb "$DISPLAY" -screen 0 1400x1000x24 >/dev/null 2>&1 &
XVFB=$!
trap 'kill $XVFB 2>/dev/null; pkill -f "RawLogViewer -l" 2>/dev/null || true' EXIT
sleep 2
(cd "$(dirname "$RAWLOG")" && RawLogViewer -l "$PLUGIN" "$(basename "$RAWLOG")" >/dev/null 2>&1 &)
sleep 14
xdotool mousemove 570 239 click 1   # "Close" of the tip-of-the-day dialog
sleep 1
win=$(xwininfo -root -tree | awk '/"RawlogViewer - Part of the MRPT project"/ {print $1; exit}')
xdotool windowsize "$win" 1400 1000
sleep 2
# Tree rows are 17 px apart, entry 0 at y = 122.
xdotool mousemove 200 $((122 + 17 * ENTRY)) click 1
sleep 2
import -window root "$OUT"
echo "wrote $OUT"
