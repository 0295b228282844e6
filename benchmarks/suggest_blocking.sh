#!/usr/bin/env bash
# Does `rdea-lab suggest` pick an experiment that fixes the Table 4 analogue's blocking rows?
#
# The emulated campaign's truth has a slow second branch that specimen 2's two tensile runs cannot
# identify, so the twin misses the blocking test's 15 s holds. This asks `suggest` for the experiment that
# would shrink the band of the blocking_force scene most, then checks it by brute force: every candidate
# inside the limits is run on the emulator, added to specimen 2's tensile runs, calibrated as reproduce
# calibrates (Nelder-Mead, --viscous-branches auto) and judged by the validation report on the campaign's
# 12 datasets (max. rel. error of the three blocking rows, Table 4's metric).
#
#   rdea-lab reproduce --out /tmp/rep && benchmarks/suggest_blocking.sh /tmp/rep [WORK]
set -euo pipefail
REP=${1:?usage: suggest_blocking.sh REPRODUCE_OUT [WORK]}
WORK=${2:-$(mktemp -d)}
mkdir -p "$WORK" && cd "$WORK"
rdea-lab suggest --params "$REP/params/calibrated.yaml" --specimen specimen2 --target blocking_force \
    --stretches 1.5 --out suggested.yaml --force | sed -n '1,10p'
mk() { # name, stretch segments, duration [s]
  cat > "$1.yaml" <<Y
name: $1
kind: tensile
sample_rate: 10 Hz
measure: [force]
limits: {max_voltage: 3 kV, max_stretch: 1.6, max_force: 50 N, max_field: 80 V/um}
stretch:
$2
voltage:
- {kind: hold, duration: $3 s, value: 0 kV}
Y
}
for D in 60 300 1200; do
  mk "hold_1.5_for_${D}s" "- {kind: ramp, duration: 2 s, to: 1.5}
- {kind: hold, duration: $D s}
- {kind: ramp, duration: 2 s, to: 1.0}" $((D + 4))
done
for R in 0.01 0.05 0.25; do
  T=$(python3 -c "print(0.5 / $R)")
  mk "ramp_1.5_at_${R}_per_s" "- {kind: ramp, duration: $T s, to: 1.5}
- {kind: ramp, duration: $T s, to: 1.0}" "$(python3 -c "print(1.0 / $R)")"
done
echo "candidate                 blocking max. rel. error [%] (specimen 1, 2, 3)  branches"
echo "none (reproduce)          $(grep '^| blocking' "$REP/validation/table4.md" | awk -F'|' '{printf "%s ", $13}')"
for y in hold_*.yaml ramp_*.yaml; do
  n=${y%.yaml}; rm -rf "$n"; mkdir -p "$n/cal"
  rdea-lab run "$y" --specimen specimen2 --backend emulator --out "$n/cal/extra.nc" > /dev/null
  cp "$REP"/datasets/specimen-2/tensile_*.nc "$n/cal/"
  rdea-lab calibrate "$n/cal" --viscous-branches auto --out "$n/cal.yaml" > /dev/null 2>&1
  rdea-lab report validation --params "$n/cal.yaml" --datasets "$REP/datasets" --out "$n/val" > /dev/null 2>&1
  printf "%-25s %s  %s\n" "$n" "$(grep '^| blocking' "$n/val/table4.md" | awk -F'|' '{printf "%s ", $13}')" \
    "$(grep -c '  - k:' "$n/cal.yaml")"
done
