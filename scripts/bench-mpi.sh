#!/usr/bin/env bash
# Frame time and per-rank memory of MPI renders against rank count (docs/benchmarks-mpi.md).
# Usage: scripts/bench-mpi.sh OUTDIR [CELLS] [RUNS]
# Every configuration runs once per round, rounds repeated RUNS times (medians reported), one
# thread per rank so that rank counts compare core for core; processor times (all ranks) measure
# the compute on a machine shared with other work. Needs Open MPI (.ci/install-deps).
set -euo pipefail
out=${1:?usage: bench-mpi.sh OUTDIR [CELLS] [RUNS]}
cells=${2:-3e7}
runs=${3:-3}
root=$(cd "$(dirname "$0")/.." && pwd)
cargo build --release -q --manifest-path "$root/Cargo.toml" -p amr-convert
cargo build --release -q --manifest-path "$root/Cargo.toml" -p amr-render --features mpi
bin="$root/target/release"
mkdir -p "$out"
file="$out/ripple.amrk"
[ -f "$file" ] || "$bin/amr-convert" synth ripple -o "$file" --cells "$cells"
args=("$file" --iso 0 --iso '0.5:#3070ff:0.4' --size 512x384 --no-shadows --ao 0 --threads 1)
mpirun_=(mpirun --oversubscribe --bind-to none)
[ "$(id -u)" = 0 ] && mpirun_+=(--allow-run-as-root)
configs=(single rep1 rep2 rep4 part1 part2 part4)
run() { # config round
  local c=$1 r=$2 json="$out/$1-$2.json" t0 t1
  t0=$(date +%s.%N)
  case $c in
    single) "$bin/amr-render" "${args[@]}" -o "$out/$c.exr" --stats-json "$json" ;;
    rep*) "${mpirun_[@]}" -n "${c#rep}" "$bin/amr-render" "${args[@]}" -o "$out/$c.exr" \
            --stats-json "$json" ;;
    part*) "${mpirun_[@]}" -n "${c#part}" "$bin/amr-render" "${args[@]}" -o "$out/$c.exr" \
             --mpi-mode partitioned --stats-json "$json" ;;
  esac
  t1=$(date +%s.%N)
  echo "$t0 $t1" | awk '{printf "%.3f\n", $2 - $1}' > "$out/$c-$r.wall"
}
for r in $(seq 1 "$runs"); do
  for c in "${configs[@]}"; do run "$c" "$r"; done
done
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
key() { grep -m1 "^  \"$2\":" "$1" | sed 's/.*: //; s/,$//'; }
# The largest value of a per-rank key (single-process files: the top-level key).
rank_max() {
  if grep -q '"per_rank"' "$1"; then
    grep '"rank":' "$1" | sed "s/.*\"$2\": \([0-9.e+]*\).*/\1/" | sort -g | tail -1
  else key "$1" "$3"; fi
}
stat() { # config expression-over-json
  for r in $(seq 1 "$runs"); do "$2" "$out/$1-$r.json"; done | median
}
ms() { key "$1" "$2" | awk '{printf "%.2f\n", $1 / 1000}'; }
frame() { if grep -q '"frame_ms"' "$1"; then ms "$1" frame_ms; else
  awk -v a="$(key "$1" extract_ms)" -v b="$(key "$1" bvh_ms)" -v c="$(key "$1" render_ms)" \
    'BEGIN {printf "%.2f\n", (a + b + c) / 1000}'; fi; }
ext() { ms "$1" extract_ms; }
bvh() { ms "$1" bvh_ms; }
ren() { ms "$1" render_ms; }
wait_() { if grep -q '"wait_ms"' "$1"; then ms "$1" wait_ms; else echo 0; fi; }
comp() { if grep -q '"composite_ms"' "$1"; then ms "$1" composite_ms; else echo 0; fi; }
sent() { if grep -q '"bytes_sent"' "$1"; then key "$1" bytes_sent | awk '{printf "%.1f\n", $1 / 1e6}'; else echo 0; fi; }
scene() { awk -v a="$(rank_max "$1" refs_bytes refs_bytes)" -v b="$(rank_max "$1" bvh_bytes bvh_bytes)" \
  -v c="$(rank_max "$1" build_scratch_bytes build_scratch_bytes)" \
  'BEGIN {printf "%.1f / %.1f\n", (a + b) / 2^20, c / 2^20}'; }
cpu() { if grep -q "\"$2\"" "$1"; then key "$1" "$2"; else echo "—"; fi; }
cpu_scene() { cpu "$1" cpu_scene_s; }
cpu_render() { cpu "$1" cpu_render_s; }
rss() { rank_max "$1" peak_rss_bytes peak_rss_bytes | awk '{printf "%.0f\n", $1 / 2^20}'; }
octs() { rank_max "$1" active_octants active_octants; }
echo "file: $(basename "$file"), $("$bin/amr-render" info "$file" | grep -m1 '^cells'), median of $runs"
echo
echo "| run | ranks | wall s | frame s | extract s | BVH s | render s | wait s | composite s | CPU s scene, all ranks | CPU s render, all ranks | MB sent | octants, max rank | refs+BVH / build scratch MiB, max rank | peak RSS MiB, max rank |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for c in "${configs[@]}"; do
  case $c in single) n=1; name="single process";; rep*) n=${c#rep}; name=replicated;;
    part*) n=${c#part}; name=partitioned;; esac
  wall=$(for r in $(seq 1 "$runs"); do cat "$out/$c-$r.wall"; done | median)
  echo "| $name | $n | $wall | $(stat "$c" frame) | $(stat "$c" ext) | $(stat "$c" bvh) | $(stat "$c" ren) | $(stat "$c" wait_) | $(stat "$c" comp) | $(stat "$c" cpu_scene) | $(stat "$c" cpu_render) | $(stat "$c" sent) | $(octs "$out/$c-1.json") | $(scene "$out/$c-1.json") | $(stat "$c" rss) |"
done
