#!/usr/bin/env bash
# Renders an nlid HTML report in headless Chromium and fails unless it rendered cleanly.
#
#   render_check.sh REPORT.html EXPECTED_CHARTS [SCREENSHOT.png] [MIN_PNG_KB]
#
# Passes (exit 0) only if
#   * Chromium is found and exits normally for both the DOM dump and the screenshot;
#   * the report's status element (written by nlid::HtmlReport's inline script on load) says the
#     script ran (data-ready="1"), no script error, failed load or CSP violation was recorded
#     (data-errors="0"), and the page holds EXPECTED_CHARTS charts, all laid out with a non-zero
#     size (data-charts = data-rendered = data-expected-charts = EXPECTED_CHARTS);
#   * the screenshot is a PNG larger than MIN_PNG_KB kB (default 20; a blank page is ~5 kB).
# Any report made with nlid::HtmlReport can be checked this way. Set CHROMIUM to pick a binary.
set -euo pipefail

if [ $# -lt 2 ]; then
  echo "usage: $0 REPORT.html EXPECTED_CHARTS [SCREENSHOT.png] [MIN_PNG_KB]" >&2
  exit 2
fi
html=$1
expected=$2
shot=${3:-${html%.html}.png}
min_kb=${4:-20}
fail() { echo "render check FAILED for '$html': $*" >&2; exit 1; }

[ -f "$html" ] || fail "report file not found"
case $expected in ''|*[!0-9]*) fail "expected chart count '$expected' is not a number" ;; esac

browser=${CHROMIUM:-}
if [ -z "$browser" ]; then
  for b in chromium chromium-browser google-chrome; do
    if command -v "$b" >/dev/null 2>&1; then browser=$b; break; fi
  done
fi
[ -n "$browser" ] || fail "no Chromium found (install the Debian package 'chromium', or set CHROMIUM)"

abs=$(cd "$(dirname "$html")" && pwd)/$(basename "$html")
profile=$(mktemp -d)
log=$(mktemp)
dom=$(mktemp)
trap 'rm -rf "$profile" "$log" "$dom"' EXIT
flags=(--headless --no-sandbox --disable-gpu --disable-quic --no-first-run
       --disable-background-networking --disable-component-update --disable-sync
       --disable-dev-shm-usage --hide-scrollbars "--user-data-dir=$profile")

# 1. DOM after load: the status element filled in by the report's script.
if ! timeout 120 "$browser" "${flags[@]}" --dump-dom "file://$abs" >"$dom" 2>"$log"; then
  tail -n 20 "$log" >&2
  fail "Chromium could not render the page (DOM dump failed)"
fi
status=$(grep -o '<div id="nlid-report-status"[^>]*>[^<]*' "$dom" | head -n 1 || true)
[ -n "$status" ] || fail "no nlid-report-status element in the rendered DOM (not an nlid report?)"
attr() { printf '%s' "$status" | sed -n "s/.* $1=\"\\([^\"]*\\)\".*/\\1/p"; }
ready=$(attr data-ready)
errors=$(attr data-errors)
charts=$(attr data-charts)
rendered=$(attr data-rendered)
declared=$(attr data-expected-charts)
messages=${status#*>}
echo "status: ready=$ready errors=$errors charts=$charts rendered=$rendered declared=$declared"
[ "$ready" = 1 ] || fail "the report's status script did not run (data-ready='$ready')"
[ "$errors" = 0 ] || fail "$errors error(s) in the page: $messages"
[ "$charts" = "$expected" ] || fail "page has $charts charts, expected $expected"
[ "$rendered" = "$expected" ] || fail "only $rendered of $expected charts were laid out with a size"
[ "$declared" = "$expected" ] || fail "the report declares $declared charts, expected $expected"

# 2. Screenshot: the page must paint something substantial.
rm -f "$shot"
if ! timeout 120 "$browser" "${flags[@]}" --window-size=1280,2400 "--screenshot=$shot" \
    "file://$abs" >"$log" 2>&1; then
  tail -n 20 "$log" >&2
  fail "Chromium could not take a screenshot"
fi
[ -f "$shot" ] || fail "no screenshot written"
[ "$(head -c 8 "$shot" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || fail "screenshot is not a PNG"
bytes=$(wc -c <"$shot")
echo "screenshot: $shot ($((bytes / 1024)) kB)"
[ "$bytes" -gt $((min_kb * 1024)) ] || fail "screenshot is only $bytes bytes (<= $min_kb kB): blank page?"
echo "render check passed: $expected charts, no errors"
