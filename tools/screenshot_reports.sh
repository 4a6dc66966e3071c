#!/bin/sh
# Screenshot report pages with headless Chromium, to look for overlapping or badly
# wrapped text: tools/screenshot_reports.sh OUT_DIR REPORT_DIR...
# Each REPORT_DIR/index.html becomes OUT_DIR/<report folder name>.png, 1400 px wide
# (the page's two-column width) and HEIGHT px tall (default 6000; set HEIGHT to change).
# Needs chromium (apt-get install chromium); --no-sandbox because it runs as root here.
set -eu
out=$1
shift
mkdir -p "$out"
for report in "$@"; do
    dir=$(cd "$report" && pwd)
    name=$(basename "$dir")
    [ "$name" = report ] && name=$(basename "$(dirname "$dir")")  # results/<study>/report
    profile=$(mktemp -d)
    chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
        --disable-background-networking --disable-component-update --disable-sync \
        --hide-scrollbars --user-data-dir="$profile" --window-size=1400,"${HEIGHT:-6000}" \
        --screenshot="$out/$name.png" "file://$dir/index.html" 2>/dev/null
    rm -rf "$profile"
    echo "$out/$name.png"
done
