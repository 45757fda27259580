#!/usr/bin/env bash
# Install Chromium (Debian's package) for the test that opens the report in a headless browser.
# Does nothing if a Chromium is already there; gives up quietly (the test then skips) where it
# cannot install one (not root, no apt-get, no network to the Debian mirrors).
set -u
for b in chromium chromium-browser google-chrome; do
  command -v "$b" >/dev/null 2>&1 && exit 0
done
if [ "$(id -u)" != "0" ] || ! command -v apt-get >/dev/null 2>&1; then
  echo "install-browser: cannot install Chromium here (not root or no apt-get); the HTML test will skip" >&2
  exit 0
fi
export DEBIAN_FRONTEND=noninteractive
if timeout 900 apt-get update -qq >/dev/null 2>&1 && \
   timeout 900 apt-get install -y -qq --no-install-recommends chromium >/dev/null 2>&1; then
  echo "install-browser: installed $(chromium --version 2>/dev/null)"
else
  echo "install-browser: apt-get could not install chromium; the HTML test will skip" >&2
fi
exit 0
