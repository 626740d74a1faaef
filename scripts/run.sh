#!/usr/bin/env bash
# One command: install what is missing, build, and start the GUI on the built-in phantom case.
# Extra arguments go to the program (for example: open CASE_FOLDER).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh --target rehearse
if [ -z "${DISPLAY:-}" ] && [ -z "${WAYLAND_DISPLAY:-}" ]; then
  echo "run: no display; starting under xvfb-run (use --screenshot PNG to see the window)" >&2
  exec xvfb-run -a -s "-screen 0 1600x900x24" build/app/rehearse "$@"
fi
exec build/app/rehearse "$@"
