#!/usr/bin/env bash
# Runs a command and samples its memory every INTERVAL seconds from /proc/PID/status:
# elapsed seconds, VmRSS, RssAnon, RssFile and VmHWM (all MiB), one tab-separated line per sample.
# Usage: scripts/rss-trace.sh OUT.tsv [INTERVAL] -- COMMAND [ARGS...]
set -euo pipefail
out=$1
shift
interval=0.2
if [[ $1 != -- ]]; then
    interval=$1
    shift
fi
[[ $1 == -- ]] || { echo "usage: $0 OUT.tsv [INTERVAL] -- COMMAND [ARGS...]" >&2; exit 2; }
shift
"$@" &
pid=$!
start=$(date +%s.%N)
printf 'seconds\tVmRSS_MiB\tRssAnon_MiB\tRssFile_MiB\tVmHWM_MiB\n' >"$out"
while [[ -r /proc/$pid/status ]]; do
    now=$(date +%s.%N)
    awk -v t="$(echo "$now - $start" | bc)" '
        /^VmRSS:/ {rss=$2} /^RssAnon:/ {anon=$2} /^RssFile:/ {file=$2} /^VmHWM:/ {hwm=$2}
        END { if (rss != "") printf "%.2f\t%.0f\t%.0f\t%.0f\t%.0f\n", t, rss/1024, anon/1024, file/1024, hwm/1024 }
    ' "/proc/$pid/status" >>"$out" 2>/dev/null || true
    sleep "$interval"
done
wait "$pid"
