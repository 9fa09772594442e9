#!/usr/bin/env bash
# Set up everything the test suite needs on a fresh machine, then run it.
#   - Debian packages for the report checks: headless Chromium + its driver, poppler (pdftoppm)
#   - a virtualenv in .venv with parambench and its test extra
# Extra arguments go to pytest (e.g. `bash tests/run.sh -k metrics`; `-n 0` runs in one process).
set -euo pipefail
cd "$(dirname "$0")/.."

need=()
command -v chromium >/dev/null 2>&1 || need+=(chromium)
command -v chromedriver >/dev/null 2>&1 || need+=(chromium-driver)
command -v pdftoppm >/dev/null 2>&1 || need+=(poppler-utils)
if [ "${#need[@]}" -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi

python3 -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip >/dev/null
.venv/bin/python -m pip install -q ".[test]"  # not editable: an editable install of a flat layout always prints a setuptools notice
# One pytest worker per core, at most 4 (pytest-xdist): on 2 cores the suite takes
# about half the time of one process; more workers would mostly add memory.
cores=$(nproc 2>/dev/null || echo 2)
workers=$(( cores < 4 ? cores : 4 ))
exec .venv/bin/python -m pytest -n "$workers" "$@"
