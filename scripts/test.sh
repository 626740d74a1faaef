#!/usr/bin/env bash
# One command: install what is missing, build everything, run every test suite, check the GUI-less
# build, and fuzz the hand-written parsers for a bounded time. Incremental on later runs.
set -euo pipefail
cd "$(dirname "$0")/.."
FUZZ_SECONDS="${FUZZ_SECONDS:-10}"
scripts/install-deps.sh
scripts/build.sh
echo "== core and command line without the GUI (REHEARSE_BUILD_GUI=OFF)"
if [ ! -f build-nogui/CMakeCache.txt ]; then cmake --preset nogui >/dev/null; fi
cmake --build build-nogui -j"$(nproc)" --target rehearse
build-nogui/app/rehearse --version
if ldd build-nogui/app/rehearse | grep -q libQt; then
  echo "the GUI-less build links Qt" >&2
  exit 1
fi

# A case the window saved is opened by this build too (test_desktop_gui asks for it).
REHEARSE_REQUIRE_NOGUI=1 ctest --test-dir build --output-on-failure -j2 --timeout 900

if [ "$FUZZ_SECONDS" -gt 0 ]; then
  scripts/fuzz.sh "$FUZZ_SECONDS"
fi
echo "== all tests passed"
