#!/usr/bin/env bash
# Set up and run the checks: ruff (lint and format) and the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh test,studies,bench
bash scripts/install-browser.sh  # for the report's headless-browser test (skips without one)
.venv/bin/ruff check .
.venv/bin/ruff format --check .
.venv/bin/python -m pytest "$@"
