#!/usr/bin/env bash
# The projector-response figures of docs/performance.md ("Projector response"): the flat
# plate of `slscan scan` on the virtual rig (true calibration, so that only the response
# differs), with 3- and 4-step fringes, a linear projector, a gamma of 2.2 and the measured
# curve, each uncorrected, corrected at decode and pre-compensated, over seeds 0-2.
# Prints one line per run: shape steps correction seed flatness_mm flatness_trimmed_mm
# plane_rms_mm phase_rms_px phase_rms_rad. Usage: benches/response/matrix.sh OUT_DIR [SEEDS]
set -euo pipefail
out=${1:?output folder}
seeds=${2:-"0 1 2"}
cargo build --release --example slscan >&2
bin=target/release/examples/slscan
mkdir -p "$out"
run() { # shape steps correction seed
  local shape=$1 steps=$2 corr=$3 seed=$4
  local dir="$out/$shape-$steps-$corr-$seed"
  local flags=(--projector-response power --projector-gamma 1)
  case $shape in
    gamma2.2) flags=(--projector-response power --projector-gamma 2.2) ;;
    measured) flags=(--projector-response measured) ;;
  esac
  "$bin" scan --out "$dir" --views 2 --true-calibration --seed "$seed" --overwrite \
    --phase-steps "$steps" --correct-response "$corr" "${flags[@]}" > "$dir.log" 2>&1 \
    || { echo "$shape $steps $corr $seed FAILED (see $dir.log)"; return; }
  python3 - "$dir/report.json" "$shape" "$steps" "$corr" "$seed" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
f = r["figures"]
fl = f["flatness"]["planes"][0]
ph = f["plate_phase"]
print(*sys.argv[2:6], f'{fl["flatness_mm"]:.4f}', f'{fl["flatness_trimmed_mm"]:.4f}', f'{fl["fit_rms_mm"]:.4f}',
      f'{ph["rms_px"]:.4f}', f'{ph["rms_rad"]:.4f}')
PY
}
for seed in $seeds; do
  for steps in 3 4; do
    run linear "$steps" none "$seed"
    for shape in gamma2.2 measured; do
      for corr in none decode precompensate; do
        run "$shape" "$steps" "$corr" "$seed"
      done
    done
  done
done
