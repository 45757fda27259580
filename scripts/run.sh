#!/usr/bin/env bash
# Set up and run the main job on built-in defaults: calibrate the bundled linkage example
# and write the calibration JSON to out/calibration.json.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
.venv/bin/simbench calibrate examples/linkage_exercise.csv --json out/calibration.json "$@"
