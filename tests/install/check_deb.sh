#!/usr/bin/env bash
# The Debian package (issue 39), as a hospital's IT would meet it: CPack writes rehearse_<version>_<arch>.deb from
# the build; lintian (errors, warnings and informational tags), desktop-file-validate and appstreamcli check it; then
# it is installed with `apt-get install ./rehearse_*.deb` into a clean Debian 12 root made here with debootstrap (the
# package's Depends must pull in everything it needs from the archive), and the installed program runs there:
# --version, `rehearse phantom` and the GUI on the built-in case with Qt's offscreen platform (a screenshot of the
# main window). Needs root (chroot) and the Debian archive; without either it fails, it does not skip.
# Usage: check_deb.sh BUILD_DIR SCRATCH_DIR
set -euo pipefail
build=$(cd "$1" && pwd) out=$2
fail() { echo "check_deb: $*" >&2; exit 1; }
[ "$(id -u)" -eq 0 ] || fail "installing into a Debian root needs root (chroot); run the tests as root"
for tool in cpack lintian debootstrap dpkg-deb desktop-file-validate appstreamcli; do
  command -v "$tool" >/dev/null || fail "$tool was not found: run scripts/install-deps.sh"
done
root="$out/root"
rm -rf --one-file-system "$out"  # never into a /proc a killed debootstrap left mounted
mkdir -p "$out/pkg" "$out/contents"

cpack --config "$build/CPackConfig.cmake" -G DEB -B "$out/pkg" >/dev/null
debs=("$out"/pkg/rehearse_*.deb)
[ ${#debs[@]} -eq 1 ] && [ -f "${debs[0]}" ] || fail "cpack wrote no single rehearse_*.deb into $out/pkg"
deb=${debs[0]}
echo "package: $(basename "$deb") ($(stat -c %s "$deb") bytes)"
depends=$(dpkg-deb -f "$deb" Depends)
for d in qt6-qpa-plugins libqt6sql6-sqlite libqt6widgets6 libopencv-core406; do
  [[ ", $depends," == *", $d"[\ ,]* ]] || fail "Depends lacks $d: $depends"
done

# The clean root is made meanwhile (debootstrap waits on the archive; lintian on the processor).
mirror=${REHEARSE_DEBIAN_MIRROR:-http://deb.debian.org/debian}
debootstrap --variant=minbase bookworm "$root" "$mirror" >"$out/debootstrap.log" 2>&1 &
debootstrap_pid=$!
# A check that fails meanwhile stops it (the next run removes the root it was making).
trap 'kill "$debootstrap_pid" 2>/dev/null && pkill -P "$debootstrap_pid" 2>/dev/null; true' EXIT
# One run shows everything (pedantic and experimental tags too); its error, warning and informational tags fail.
# A lintian that failed without a tag (it could not run) fails too.
lintian_status=0
lintian --info --pedantic --display-experimental "$deb" >"$out/lintian.log" 2>&1 || lintian_status=$?
grep -v 'running with root privileges' "$out/lintian.log" || true
if [ "$lintian_status" -ne 0 ] || grep -qE '^[EWI]: ' "$out/lintian.log"; then
  wait $debootstrap_pid || true
  fail "lintian reports errors, warnings or informational tags (above)"
fi
echo "lintian: no errors, warnings or informational tags"

dpkg-deb -x "$deb" "$out/contents"
id=org.rehearse.Rehearse
desktop-file-validate "$out/contents/usr/share/applications/$id.desktop" || fail "the packaged desktop entry does not validate"
appstreamcli validate --no-net "$out/contents/usr/share/metainfo/$id.metainfo.xml" >/dev/null ||
  fail "the packaged metainfo does not validate"

# A clean Debian 12 root from the same archive this machine uses (its own apt sources, with the security updates).
wait $debootstrap_pid || fail "debootstrap could not make a Debian 12 root from $mirror (see $out/debootstrap.log)"
# dpkg without a sync per file (the root is thrown away; what Debian's own image builders do): the install takes
# half the time. Only the package's Depends are installed (--no-install-recommends): they alone must make it run.
echo force-unsafe-io > "$root/etc/dpkg/dpkg.cfg.d/unsafe-io"
if [ -f /etc/apt/sources.list.d/debian.sources ]; then
  rm -f "$root/etc/apt/sources.list"
  cp /etc/apt/sources.list.d/debian.sources "$root/etc/apt/sources.list.d/"
fi
cp "$deb" "$root/tmp/"
export DEBIAN_FRONTEND=noninteractive
{ chroot "$root" apt-get update -qq && chroot "$root" apt-get install -y -qq --no-install-recommends "/tmp/$(basename "$deb")"; } \
  >"$out/apt.log" 2>&1 || { tail -20 "$out/apt.log" >&2; fail "apt-get install ./$(basename "$deb") failed in the clean root"; }
echo "installed into a clean root with $(grep -c '^Setting up' "$out/apt.log") packages from the archive"

in_root() { chroot "$root" env -i PATH=/usr/bin:/bin HOME=/tmp LANG=C.UTF-8 "$@"; }
version=$(in_root rehearse --version) || fail "the installed rehearse --version failed"
echo "installed: $version"
[[ "$version" == "rehearse 0.1.0 ("* ]] || fail "unexpected version line: $version"
in_root rehearse phantom --out /tmp/case || fail "the installed rehearse phantom failed"
for f in case.json organ.msh frame.png camera.yaml; do
  [ -s "$root/tmp/case/$f" ] || fail "rehearse phantom wrote no $f"
done
in_root env QT_QPA_PLATFORM=offscreen rehearse open --screenshot /tmp/window.png >"$out/gui.log" 2>&1 ||
  { cat "$out/gui.log" >&2; fail "the installed GUI did not open the built-in case offscreen"; }
shot="$root/tmp/window.png"
[ -f "$shot" ] || fail "the GUI wrote no screenshot"
# The PNG's own header: width and height of the main window, and enough content that it is not a blank window
# (the built-in case's main window compresses to about 250 kB; an empty grey window to a few kB).
read -r w h < <(od -An -tu1 -j16 -N8 "$shot" | awk '{print $1*16777216+$2*65536+$3*256+$4, $5*16777216+$6*65536+$7*256+$8}')
size=$(stat -c %s "$shot")
echo "the installed GUI's main window: ${w}x${h}, $size bytes"
[ "$(head -c 8 "$shot" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || fail "the screenshot is not a PNG"
[ "$w" -ge 800 ] && [ "$h" -ge 500 ] && [ "$size" -gt 60000 ] || fail "the screenshot looks empty (${w}x${h}, $size bytes)"
cp "$shot" "$out/window.png"
rm -rf --one-file-system "$root"
echo "check_deb: the package installs into a clean Debian 12 root and runs there"
