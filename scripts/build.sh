#!/usr/bin/env bash
# Configures (once) and builds the release tree in build/. Incremental on later runs.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -f build/CMakeCache.txt ]; then
  cmake --preset release
fi
cmake --build build -j"$(nproc)" "$@"
