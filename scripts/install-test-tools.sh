#!/usr/bin/env bash
# Install the optional command-line tools the test suite cross-checks against.
#
# - tshark (Wireshark's command-line analyser), used by tests/crosscheck/test_tshark.py together with
#   pymavlink's generated Lua dissector;
# - chromium (Debian's package: headless Chromium), which loads `mavscope report`'s page in
#   tests/report/test_browser.py (the rendered DOM, screenshots, no request, no console error).
#
# - Idempotent and quick: installs only the tools missing from PATH, and does nothing when both are there.
# - Non-interactive: DEBIAN_FRONTEND=noninteractive, and the wireshark-common debconf
#   question ("should non-superusers be able to capture packets?") is preseeded to "false".
# - Installs from Debian packages only (apt-get), as root or through `sudo -n`.
# - On failure prints one line starting with "install-test-tools:" on stderr per tool and exits 1 (after
#   trying every tool); .ci/run carries on and the tests of a missing tool skip with a visible reason.
set -uo pipefail

fail() {
    echo "install-test-tools: $*" >&2
    exit 1
}

missing=()
command -v tshark >/dev/null 2>&1 || missing+=(tshark)
command -v chromium >/dev/null 2>&1 || missing+=(chromium)
if [ "${#missing[@]}" -eq 0 ]; then
    exit 0
fi

if [ "$(id -u)" -eq 0 ]; then
    SUDO=()
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    SUDO=(sudo -n)
else
    fail "${missing[*]} missing and this is not root and 'sudo -n' is not available: run 'apt-get install ${missing[*]}' as root"
fi

command -v apt-get >/dev/null 2>&1 || fail "${missing[*]} missing and apt-get is not available on this system"

export DEBIAN_FRONTEND=noninteractive
log="$(mktemp)"
trap 'rm -f "$log"' EXIT

if [[ " ${missing[*]} " == *" tshark "* ]] && command -v debconf-set-selections >/dev/null 2>&1; then
    echo "wireshark-common wireshark-common/install-setuid boolean false" \
        | "${SUDO[@]}" debconf-set-selections >>"$log" 2>&1 \
        || fail "could not preseed debconf for wireshark-common (see: debconf-set-selections)"
fi

install_package() {
    "${SUDO[@]}" apt-get install -y -qq --no-install-recommends \
        -o Dpkg::Options::=--force-confdef -o Dpkg::Options::=--force-confold \
        "$1" >>"$log" 2>&1
}

updated=0
status=0
for package in "${missing[@]}"; do
    # Try with the package lists the machine has; when they are missing or stale (404s), refresh once.
    if ! install_package "$package"; then
        if [ "$updated" -eq 0 ]; then
            updated=1
            "${SUDO[@]}" apt-get update -qq >>"$log" 2>&1 \
                || fail "apt-get update failed: $(tail -n 1 "$log")"
        fi
        if ! install_package "$package"; then
            echo "install-test-tools: apt-get install $package failed: $(tail -n 1 "$log")" >&2
            status=1
            continue
        fi
    fi
    if ! command -v "$package" >/dev/null 2>&1; then
        echo "install-test-tools: apt-get reported success but $package is not on PATH" >&2
        status=1
        continue
    fi
    case "$package" in
        tshark) echo "install-test-tools: installed $(tshark --version 2>/dev/null | head -n 1)" ;;
        chromium) echo "install-test-tools: installed $(chromium --version 2>/dev/null | head -n 1)" ;;
    esac
done
exit "$status"
