#!/usr/bin/env bash
# Create .venv (Python >= 3.11) and install simbench into it with the given extras.
# Usage: scripts/setup.sh [EXTRAS]   e.g. scripts/setup.sh test
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-}"
if [ ! -x .venv/bin/python ]; then
  py=""
  for cand in "${PYTHON:-}" python3.11 python3.12 python3.13 python3; do
    [ -n "$cand" ] || continue
    if command -v "$cand" >/dev/null 2>&1 &&
       "$cand" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
      py="$cand"; break
    fi
  done
  if [ -z "$py" ]; then
    echo "simbench setup: need Python >= 3.11 (set PYTHON=/path/to/python3.11)" >&2
    exit 1
  fi
  "$py" -m venv .venv
  .venv/bin/python -m pip install --quiet --upgrade pip > /dev/null 2>&1 || true
fi
spec="."
[ -n "$extras" ] && spec=".[$extras]"
# pip's chatter goes to a log that is shown only if the install fails
if ! .venv/bin/python -m pip install --quiet --disable-pip-version-check -e "$spec" > .venv/setup.log 2>&1; then
  cat .venv/setup.log >&2
  echo "simbench setup: pip install -e '$spec' failed (log above, also in .venv/setup.log)" >&2
  exit 1
fi
