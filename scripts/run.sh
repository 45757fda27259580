#!/usr/bin/env bash
# Set up and run the main job on built-in defaults: `simbench validate` reproduces O'Brien et
# al.'s linkage and human experiments and Fontaine et al.'s sourceless orientation in simulation,
# scores them against the truth, and writes the report to reports/ (index.md, index.html,
# results.json, images). Extra arguments go to `simbench validate` (e.g. --quick, --out DIR).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh studies,bench
.venv/bin/simbench validate "$@"
