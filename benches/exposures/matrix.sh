#!/usr/bin/env bash
# The exposure-fusion figures of docs/performance.md ("Dark and shiny objects"): `slscan scan`
# on the virtual rig at half resolution (--downscale 2) of the dumbbell in each finish (matte
# plaster, black plastic of albedo 0.04, glossy plastic whose highlights saturate the camera),
# with one exposure (the camera's own), automatic exposures fused per pixel from the longest
# unsaturated one, and the same fused as radiance, over seeds 0-2.
# Prints one line per run: finish exposures seed merged_points first_view_points rms_mm
# form_left_mm form_right_mm form_trimmed_left_mm form_trimmed_right_mm spacing_mm
# capture_s exposures_ms. Usage: benches/exposures/matrix.sh OUT_DIR [SEEDS] [DOWNSCALE]
set -euo pipefail
out=${1:?output folder}
seeds=${2:-"0 1 2"}
downscale=${3:-2}
cargo build --release --example slscan >&2
bin=target/release/examples/slscan
mkdir -p "$out"
run() { # finish mode seed
  local finish=$1 mode=$2 seed=$3
  local dir="$out/$finish-$mode-$seed"
  local flags=()
  case $mode in
    auto) flags=(--exposures auto) ;;
    radiance) flags=(--exposures auto --fusion radiance) ;;
  esac
  "$bin" scan --out "$dir" --downscale "$downscale" --no-plate --seed "$seed" --overwrite \
    --finish "$finish" "${flags[@]}" > "$dir.log" 2>&1 \
    || { echo "$finish $mode $seed FAILED: $(grep -o 'error: .*' "$dir.log" | head -1)"; return; }
  python3 - "$dir/report.json" "$finish" "$mode" "$seed" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
f = r["figures"]
a = f["accuracy"]
s = {x["name"]: x for x in a["spheres"]}
first = sum(x["points"] for x in f["first_view"]["spheres"])
cap = sum(st["ms"] for st in r["stages"] if st["name"] == "capture") / 1000
pair = a["sphere_pairs"][0]["sphere_spacing_mm"] if a.get("sphere_pairs") else float("nan")
times = ",".join(f"{t:.2f}" for t in f["exposures"]["times_ms"]) or "camera"
print(*sys.argv[2:5], f["merged_points"], first, f'{a["rms_to_reference_mm"]:.4f}',
      f'{s["sphere_left"]["probing_form_mm"]:.4f}', f'{s["sphere_right"]["probing_form_mm"]:.4f}',
      f'{s["sphere_left"]["probing_form_trimmed_mm"]:.4f}', f'{s["sphere_right"]["probing_form_trimmed_mm"]:.4f}',
      f'{pair:+.4f}', f'{cap:.1f}', times)
PY
}
for seed in $seeds; do
  for finish in matte dark glossy; do
    for mode in one auto radiance; do
      run "$finish" "$mode" "$seed"
    done
  done
done
