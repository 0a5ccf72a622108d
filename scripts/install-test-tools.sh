#!/usr/bin/env bash
# Install the optional command-line tools the test suite cross-checks against.
#
# Today that is tshark (Wireshark's command-line analyser), used by
# tests/crosscheck/test_tshark.py together with pymavlink's generated Lua dissector.
#
# - Idempotent and quick: does nothing when `tshark` is already on PATH.
# - Non-interactive: DEBIAN_FRONTEND=noninteractive, and the wireshark-common debconf
#   question ("should non-superusers be able to capture packets?") is preseeded to "false".
# - Installs from Debian packages only (apt-get), as root or through `sudo -n`.
# - On failure prints one line starting with "install-test-tools:" on stderr and exits 1;
#   .ci/run carries on and the tshark tests skip with a visible reason.
set -uo pipefail

fail() {
    echo "install-test-tools: $*" >&2
    exit 1
}

if command -v tshark >/dev/null 2>&1; then
    exit 0
fi

if [ "$(id -u)" -eq 0 ]; then
    SUDO=()
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    SUDO=(sudo -n)
else
    fail "tshark is missing and this is not root and 'sudo -n' is not available: run 'apt-get install tshark' as root"
fi

command -v apt-get >/dev/null 2>&1 || fail "tshark is missing and apt-get is not available on this system"

export DEBIAN_FRONTEND=noninteractive
log="$(mktemp)"
trap 'rm -f "$log"' EXIT

if command -v debconf-set-selections >/dev/null 2>&1; then
    echo "wireshark-common wireshark-common/install-setuid boolean false" \
        | "${SUDO[@]}" debconf-set-selections >>"$log" 2>&1 \
        || fail "could not preseed debconf for wireshark-common (see: debconf-set-selections)"
fi

install_tshark() {
    "${SUDO[@]}" apt-get install -y -qq --no-install-recommends \
        -o Dpkg::Options::=--force-confdef -o Dpkg::Options::=--force-confold \
        tshark >>"$log" 2>&1
}

# Try with the package lists the machine has; when they are missing or stale (404s), refresh once.
if ! install_tshark; then
    "${SUDO[@]}" apt-get update -qq >>"$log" 2>&1 \
        || fail "apt-get update failed: $(tail -n 1 "$log")"
    install_tshark || fail "apt-get install tshark failed: $(tail -n 1 "$log")"
fi

command -v tshark >/dev/null 2>&1 || fail "apt-get reported success but tshark is not on PATH"
echo "install-test-tools: installed $(tshark --version 2>/dev/null | head -n 1)"
