#!/usr/bin/env bash
# Installs the Debian 12 packages Rehearse needs (as root, or through sudo). Idempotent: does nothing
# when everything is already installed.
set -euo pipefail
PACKAGES=(
  build-essential cmake ninja-build ccache pkg-config clang libclang-rt-14-dev
  qt6-base-dev qt6-base-dev-tools libqt6opengl6-dev qt6-charts-dev libqt6sql6-sqlite libgl-dev libegl-dev
  libeigen3-dev libopencv-dev libopencv-contrib-dev libcgal-dev libgmp-dev libmpfr-dev libboost-dev
  libassimp-dev libsuitesparse-dev libopenblas-dev libtbb-dev
  # The reference BLAS and LAPACK: test_recording replays with them as the machine's libblas.so.3 (issue 60).
  libblas3 liblapack3 nlohmann-json3-dev libtinyxml2-dev zlib1g-dev libsqlite3-dev libssl-dev libpq-dev libspnav-dev
  # The review's PDF report (cairo and pango, below the GUI).
  libcairo2-dev libpango1.0-dev
  calculix-ccx xvfb xauth libgl1-mesa-dri fonts-dejavu-core poppler-utils
  # The server test_training starts; Qt SQL's PostgreSQL driver for its probe of a publisher at work (the program
  # itself reaches the training database through libpq).
  postgresql libqt6sql6-psql
  desktop-file-utils appstream shared-mime-info man-db lintian debootstrap
  # ITK reads segmentations (NRRD, NIfTI, MetaImage); its CMake configuration names GDCM's tools, hence gdcm-tools.
  libinsighttoolkit5-dev libgdcm-tools
  qt6-l10n-tools qt6-tools-dev
)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null; then SUDO="sudo"; else
    echo "install-deps: run as root (or install sudo) to install: ${missing[*]}" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
