#!/usr/bin/env bash
# Builds the Debian package: install what is missing, build the program, its man page, changelog and user guide, and write
# build/pkg/rehearse_<version>_<arch>.deb with CPack. Install it with: apt-get install ./build/pkg/rehearse_*.deb
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh --target rehearse rehearse_manpage rehearse_changelog rehearse_guide
rm -f build/pkg/rehearse_*.deb
cpack --config build/CPackConfig.cmake -G DEB -B build/pkg >/dev/null
ls build/pkg/rehearse_*.deb
