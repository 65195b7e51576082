#!/usr/bin/env bash
# The Debian package (tools/package/CMakeLists.txt), built by CPack from this build tree and
# checked as a site would meet it: its control fields and dependencies, its files, its conffiles
# and maintainer scripts, the systemd unit through `systemd-analyze verify` in a root made of the
# package's files and the host's systemd units, and the packaged binaries run from that root (the
# server under systemd's notify protocol: notify_check.py). DDS domain 186.
#
#   tests/package/package_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build="$(cd "$1" && pwd)"
source="$(cd "$2" && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
fail() { echo "package_test: $*" >&2; exit 1; }

(cd "$work" && cpack --config "$build/CPackConfig.cmake" -G DEB -B "$work/out" >"$work/cpack.log" 2>&1) ||
  { cat "$work/cpack.log"; fail "cpack failed"; }
deb="$(ls "$work"/out/ignav_*.deb)"
echo "package_test: $(basename "$deb"), $(du -h "$deb" | cut -f1)"

# Control: name, version from the project, dependencies found by dpkg-shlibdeps plus our own.
[ "$(dpkg-deb -f "$deb" Package)" = ignav ] || fail "Package is not ignav"
version="$(sed -n 's/^project(ignav VERSION \([0-9.]*\).*/\1/p' "$source/CMakeLists.txt")"
[ "$(dpkg-deb -f "$deb" Version)" = "$version" ] || fail "Version is not $version"
depends="$(dpkg-deb -f "$deb" Depends)"
for d in adduser systemd libddsc0 libsystemd0 libyaml-cpp; do
  grep -q "$d" <<<"$depends" || fail "Depends lacks $d: $depends"
done

# Files.
dpkg-deb -c "$deb" | awk '{print $6}' >"$work/files"
for f in ./usr/bin/ignav-server ./usr/bin/ignavctl ./usr/bin/ignav-plan \
  ./etc/ignav/server.yaml ./etc/ignav/tissues.yaml ./etc/ignav/robots/torabi2014.yaml \
  ./etc/ignav/dds/loopback.xml ./lib/systemd/system/ignav-server.service \
  ./usr/share/ignav/security/make-test-pki.sh ./usr/share/doc/ignav/DEPLOYMENT.md; do
  grep -qx "$f" "$work/files" || fail "$f is not in the package"
done
if grep -q '^./var/lib/ignav' "$work/files"; then fail "the package ships /var/lib/ignav (postinst makes it)"; fi

# Control files: every /etc file a conffile (an upgrade keeps a site's edits), scripts that parse.
dpkg-deb -e "$deb" "$work/control"
for f in $(grep '^./etc/.*[^/]$' "$work/files" | sed 's/^\.//'); do
  grep -qx "$f" "$work/control/conffiles" || fail "$f is not a conffile"
done
for script in postinst prerm postrm; do
  [ -x "$work/control/$script" ] || fail "$script missing or not executable"
  sh -n "$work/control/$script" || fail "$script does not parse"
done
grep -q 'adduser --system' "$work/control/postinst" || fail "postinst makes no service user"
if grep -q 'rm .*/var/lib/ignav' "$work/control/postrm"; then fail "postrm deletes the sessions"; fi

# The unit, in a root of the package's files and the host's units (systemd-analyze wants
# sysinit.target and friends; Debian 12 keeps them in /usr/lib).
root="$work/root"
dpkg-deb -x "$deb" "$root"
mkdir -p "$root/usr/lib/systemd"
cp -a /usr/lib/systemd/system "$root/usr/lib/systemd/"
cp "$root/lib/systemd/system/ignav-server.service" "$root/usr/lib/systemd/system/"
rm -rf "$root/lib" && ln -s usr/lib "$root/lib"
unit=/lib/systemd/system/ignav-server.service
if ! out="$(systemd-analyze verify --root="$root" "$unit" 2>&1)" || [ -n "$out" ]; then
  fail "systemd-analyze verify: $out"
fi
grep -qx 'Type=notify' "$root$unit" || fail "the unit is not Type=notify"
grep -q '^WatchdogSec=' "$root$unit" || fail "the unit has no watchdog"
grep -qx 'User=ignav' "$root$unit" || fail "the unit does not run as the ignav user"
# The check can fail: the same unit naming a program the root does not have.
sed 's#^ExecStart=/usr/bin/ignav-server#ExecStart=/usr/bin/ignav-absent#' "$root$unit" \
  >"$root/usr/lib/systemd/system/ignav-absent.service"
if systemd-analyze verify --root="$root" /lib/systemd/system/ignav-absent.service >/dev/null 2>&1; then
  fail "systemd-analyze verify passed a unit whose program is missing"
fi

# The packaged configuration keeps sessions under the state folder; the packaged programs run.
grep -q '^  session_root: /var/lib/ignav/sessions' "$root/etc/ignav/server.yaml" ||
  fail "the packaged server.yaml does not keep sessions in /var/lib/ignav"
"$root/usr/bin/ignavctl" --help >/dev/null || fail "ignavctl --help"
"$root/usr/bin/ignav-plan" --help >/dev/null || fail "ignav-plan --help"
python3 "$source/tests/package/notify_check.py" "$root/usr/bin/ignav-server" \
  "$root/etc/ignav/server.yaml" 186 "$work/session" || fail "the packaged server under sd_notify"
[ -s "$work/session/journal.jsonl" ] || fail "the packaged server wrote no journal"
echo "package_test: ok"
