#!/usr/bin/env bash
# Compression ratio and read speed (warm and cold page cache) of raw against zstd-compressed
# .amrk files holding the same data. Usage: scripts/bench-compression.sh OUTDIR [CELLS] [PLOTFILE]
# Drops a file's cached pages with `dd iflag=nocache count=0` (GNU coreutils) before each cold run.
set -euo pipefail
out=${1:?usage: bench-compression.sh OUTDIR [CELLS] [PLOTFILE]}
cells=${2:-1e8}
plotfile=${3:-}
root=$(cd "$(dirname "$0")/.." && pwd)
cargo build --release -q --manifest-path "$root/Cargo.toml" -p amr-convert -p amr-bench
bin="$root/target/release"
mkdir -p "$out"
pairs=()
for case in blobs ripple; do
  "$bin/amr-convert" synth "$case" -o "$out/$case.amrk" --cells "$cells"
  "$bin/amr-convert" synth "$case" -o "$out/$case-zstd.amrk" --cells "$cells" --compress
  pairs+=("$case")
done
if [ -n "$plotfile" ]; then
  name=$(basename "$plotfile")
  "$bin/amr-convert" "$plotfile" -o "$out/$name.amrk"
  "$bin/amr-convert" "$plotfile" -o "$out/$name-zstd.amrk" --compress
  pairs+=("$name")
fi
drop() { dd if="$1" iflag=nocache count=0 status=none; }
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
echo "| data | raw bytes | zstd bytes | ratio | warm raw s | warm zstd s | cold raw s | cold zstd s |"
echo "|---|---|---|---|---|---|---|---|"
for p in "${pairs[@]}"; do
  raw="$out/$p.amrk"; z="$out/$p-zstd.amrk"
  declare -A t=()
  for mode in warm cold; do
    for f in "$raw" "$z"; do
      runs=()
      for _ in 1 2 3 4 5; do
        [ "$mode" = cold ] && drop "$f"
        runs+=("$("$bin/amr-bench" read "$f" | tail -1 | awk -F'|' '{print $5}')")
      done
      t[$mode,$f]=$(printf '%s\n' "${runs[@]}" | median)
    done
  done
  rb=$(stat -c %s "$raw"); zb=$(stat -c %s "$z")
  echo "| $p | $rb | $zb | $(awk "BEGIN {printf \"%.2f\", $rb/$zb}") | ${t[warm,$raw]} | ${t[warm,$z]} | ${t[cold,$raw]} | ${t[cold,$z]} |"
done
