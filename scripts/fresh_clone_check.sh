#!/usr/bin/env bash
# Issue 14's first-contact check: clone the committed HEAD into an empty temporary folder that has no
# ../shared beside it, then run the README's two commands there (`make test`, and `make demo` unless
# --no-demo). Run it before stopping; it is not a test because it re-installs the environment (minutes).
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
tmp="$(mktemp -d /tmp/rtchannel-fresh.XXXXXX)"
trap 'echo "clone left in $tmp"' EXIT
git clone -q "$repo" "$tmp/rtchannel"
cd "$tmp/rtchannel"
[ ! -e ../shared ] || { echo "error: $tmp/shared exists; the check needs a folder without it" >&2; exit 2; }
make test
if [ "${1:-}" != "--no-demo" ]; then
  make demo
  ls out/demo/*/signature.h5 out/demo/*/*.png >/dev/null
fi
echo "fresh clone OK: $tmp/rtchannel"
