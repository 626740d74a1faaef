#!/usr/bin/env bash
# The installed layout (issue 39): `cmake --install` of the build into a scratch prefix, then what a desktop and a
# package checker would look at, with their own tools: the desktop entry (desktop-file-validate), the AppStream
# metainfo (appstreamcli validate --no-net), the MIME type of case files (update-mime-database maps *.rehearse to it),
# `rehearse --version` naming the revision git reports for the sources, the man page (man --warnings) covering every
# sub-command, and the installed program writing the built-in case without the build tree.  Usage: check_install.sh BUILD_DIR SOURCE_DIR SCRATCH_DIR
set -euo pipefail
build=$1 src=$2 out=$3
fail() { echo "check_install: $*" >&2; exit 1; }
for tool in desktop-file-validate appstreamcli update-mime-database man; do
  command -v "$tool" >/dev/null || fail "$tool was not found: run scripts/install-deps.sh"
done
rm -rf "$out"
cmake --install "$build" --prefix "$out" >/dev/null
id=org.rehearse.Rehearse
for f in bin/rehearse share/applications/$id.desktop share/metainfo/$id.metainfo.xml share/mime/packages/$id.xml \
         share/icons/hicolor/scalable/apps/$id.svg share/doc/rehearse/README.md; do
  [ -f "$out/$f" ] || fail "not installed: $f"
done
desktop-file-validate "$out/share/applications/$id.desktop" || fail "the desktop entry does not validate"
grep -q '^Exec=rehearse open %f$' "$out/share/applications/$id.desktop" || fail "the desktop entry does not open files"
appstreamcli validate --no-net "$out/share/metainfo/$id.metainfo.xml" || fail "the metainfo does not validate"
# Screenshots: named only where the build says docs/ is published (REHEARSE_SCREENSHOT_URL); written here with an
# address under the reserved .example domain, the metainfo validates with them, names the program's own pictures
# from docs/, and an address that is not https is refused.
shots="$out/with-screenshots.metainfo.xml"
cmake -DIN="$src/packaging/$id.metainfo.xml.in" -DOUTPUT="$shots" -DURL=https://rehearse.example/docs \
  -DDOCS="$src/docs" -P "$src/cmake/Metainfo.cmake" || fail "the metainfo with screenshots was not written"
appstreamcli validate --no-net "$shots" || fail "the metainfo with screenshots does not validate"
n=$(grep -c '<image>https://rehearse.example/docs/[a-z0-9-]*\.png</image>' "$shots" || true)
[ "$n" -ge 3 ] && grep -q '<screenshot type="default">' "$shots" || fail "the metainfo names $n screenshots"
grep -q '<screenshot' "$out/share/metainfo/$id.metainfo.xml" && [ -z "$(sed -n 's/^REHEARSE_SCREENSHOT_URL:STRING=//p' "$build/CMakeCache.txt")" ] &&
  fail "the metainfo names screenshots although the build names no address for them"
if cmake -DIN="$src/packaging/$id.metainfo.xml.in" -DOUTPUT="$out/refused.xml" -DURL=http://rehearse.example/ \
     -P "$src/cmake/Metainfo.cmake" 2>"$out/refused.txt"; then fail "an http:// screenshot address was taken"; fi
grep -q "must be an https:// address" "$out/refused.txt" || fail "the refusal does not say why: $(cat "$out/refused.txt")"
echo "metainfo: $n screenshots named when an address is given; none without one"
update-mime-database "$out/share/mime"
grep -qx 'application/x-rehearse-case:\*.rehearse' "$out/share/mime/globs" || fail "*.rehearse is not a case file's type"
version=$("$out/bin/rehearse" --version)
echo "installed: $version"
if rev=$(git -C "$src" rev-parse --short=12 HEAD 2>/dev/null); then
  [[ "$version" == "rehearse "*"(git $rev"* ]] || fail "--version does not name the revision $rev: $version"
else
  [[ "$version" == *"revision unknown"* ]] || fail "--version claims a revision outside a git checkout: $version"
fi
# The man page: renders without a warning (as lintian checks it) and has a part for every sub-command the installed
# program lists in its --help (those that answer `NAME --help`).
page="$out/share/man/man1/rehearse.1.gz"
[ -f "$page" ] || fail "not installed: share/man/man1/rehearse.1.gz"
warnings=$(LC_ALL=C.UTF-8 MANROFFSEQ='' MANWIDTH=80 man --warnings -E UTF-8 -l -Tutf8 -Z "$page" 2>&1 >/dev/null)
[ -z "$warnings" ] || fail "the man page renders with warnings: $warnings"
listed=0
for name in $("$out/bin/rehearse" --help | sed -n 's/^  rehearse \([a-z][a-z-]*\).*/\1/p' | sort -u); do
  "$out/bin/rehearse" "$name" --help >/dev/null 2>&1 || continue
  gzip -dc "$page" | grep -qx ".SS $name" || fail "the man page has no part for 'rehearse $name'"
  listed=$((listed + 1))
done
[ "$listed" -ge 5 ] || fail "only $listed sub-commands found in --help"
echo "the man page covers $listed sub-commands"
"$out/bin/rehearse" phantom --out "$out/phantom-case" >/dev/null || fail "the installed program cannot write the built-in case"
[ -n "$(ls -A "$out/phantom-case")" ] || fail "the built-in case folder is empty"
echo "check_install: $(cd "$out" && find . -type f -not -path './phantom-case/*' | wc -l) files installed and checked"
