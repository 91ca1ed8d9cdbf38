#!/usr/bin/env bash
# Headless Chromium and its WebDriver from Debian's packages, for tests/app/test_browser.py.
# Idempotent: does nothing when both are installed.  Never fails the caller: without them (no
# root, no package registry) the browser tests skip and say why.
set -uo pipefail
if [ -x /usr/bin/chromium ] && [ -x /usr/bin/chromedriver ]; then
    exit 0
fi
SUDO=""
if [ "$(id -u)" != "0" ]; then
    if command -v sudo >/dev/null && sudo -n true 2>/dev/null; then SUDO="sudo -n"; else
        echo "install-browser: not root; the browser tests will skip" >&2
        exit 0
    fi
fi
export DEBIAN_FRONTEND=noninteractive
if ! { $SUDO apt-get update -qq \
    && $SUDO apt-get install -y -qq --no-install-recommends -o DPkg::Lock::Timeout=300 \
        chromium chromium-driver fonts-dejavu-core; }; then
    echo "install-browser: apt-get could not install chromium; the browser tests will skip" >&2
fi
exit 0
