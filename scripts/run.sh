#!/usr/bin/env bash
# Set up and run the main job on built-in defaults:
#  1. simulate O'Brien's linkage through a 45 s "exercise" session at 120 Hz (MuJoCo physics,
#     ideal sensors) -> out/linkage_exercise.h5, its pose CSV and its truth JSON;
#  2. calibrate it -> out/calibration_sim.json (recovers the truth to rounding);
#  3. calibrate the bundled noisy example -> out/calibration.json.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
sb=.venv/bin/simbench
$sb simulate --model linkage --motion exercise --duration 45 --rate 120 --seed 1 \
  -o out/linkage_exercise.h5 --csv out/linkage_exercise.csv --truth-json out/linkage_exercise_truth.json
echo
$sb calibrate out/linkage_exercise.h5 --json out/calibration_sim.json
echo
$sb calibrate examples/linkage_exercise.csv --json out/calibration.json "$@"
