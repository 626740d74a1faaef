#!/usr/bin/env bash
# Builds the Debian package: install what is missing, build the program, its man page, changelog and user guide, and write
# build/pkg/rehearse_<version>_<arch>.deb with CPack. Install it with: apt-get install ./build/pkg/rehearse_*.deb
# REHEARSE_SCREENSHOT_URL=https://... (where docs/ is published) puts the screenshots into the AppStream metainfo.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
# Where docs/ is published, if it is (https): the AppStream metainfo then names the screenshots there.
if [ -n "${REHEARSE_SCREENSHOT_URL+set}" ]; then
  if [ -f build/CMakeCache.txt ]; then cmake build -DREHEARSE_SCREENSHOT_URL="$REHEARSE_SCREENSHOT_URL" >/dev/null
  else cmake --preset release -DREHEARSE_SCREENSHOT_URL="$REHEARSE_SCREENSHOT_URL" >/dev/null; fi
fi
scripts/build.sh --target rehearse rehearse_manpage rehearse_changelog rehearse_guide
rm -f build/pkg/rehearse_*.deb
cpack --config build/CPackConfig.cmake -G DEB -B build/pkg >/dev/null
ls build/pkg/rehearse_*.deb
