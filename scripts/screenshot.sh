#!/usr/bin/env bash
# Regenerates the README screenshot: the app itself, under Xvfb, on the built-in case.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh --target rehearse
mkdir -p docs
xvfb-run -a -s "-screen 0 1600x900x24" build/app/rehearse --screenshot docs/screenshot.png "$@"
echo "wrote docs/screenshot.png"
