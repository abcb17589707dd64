#!/usr/bin/env bash
# Fuzzes a cohortforge server against the checked-in openapi/openapi.json with schemathesis:
# every check (5xx, status codes, content types, headers and bodies against the spec,
# negative/positive data, auth), a fixed seed and a time budget. Exits non-zero on any
# failure; the exceptions we accept, each with its reason, are in scripts/schemathesis.toml.
#
# Usage:
#   scripts/schemathesis.sh                          # starts its own server with tokens
#   scripts/schemathesis.sh --base-url URL --token T # an already running server
#   extra arguments after -- go to `schemathesis run` (e.g. -- --include-tag meshes)
#
# Environment: SCHEMATHESIS_SECONDS (time budget, default 120), SCHEMATHESIS_SEED (default 1),
# SCHEMATHESIS_REPORT_DIR (reports; default a temp dir, printed), COHORTFORGE_VENV,
# COHORTFORGE_BIN, SCHEMATHESIS (pip spec, default schemathesis==4.32.5).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/ci_common.sh"

BASE=""
TOKEN=""
EXTRA=()
while [ $# -gt 0 ]; do
  case "$1" in
    --base-url) BASE="$2"; shift 2 ;;
    --token) TOKEN="$2"; shift 2 ;;
    --cohortforge) BIN="$2"; shift 2 ;;
    --) shift; EXTRA=("$@"); break ;;
    -h|--help) sed -n '2,/^set /{/^#/p}' "$0"; exit 0 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
SECONDS_BUDGET="${SCHEMATHESIS_SECONDS:-120}"
SEED="${SCHEMATHESIS_SEED:-1}"
REPORT_DIR="${SCHEMATHESIS_REPORT_DIR:-$(mktemp -d "${TMPDIR:-/tmp}/schemathesis-report.XXXXXX")}"
mkdir -p "$REPORT_DIR"

trap stop_server EXIT
ensure_venv "${SCHEMATHESIS:-schemathesis==4.32.5}"
echo "schemathesis $("$VENV/bin/pip" show schemathesis | sed -n 's/^Version: //p')" >&2

if [ -z "$BASE" ]; then
  # Our own server, with both tokens configured (src/config.rs: at least 16 characters).
  TOKEN="$("$VENV/bin/python" -c 'import secrets; print("admin-" + secrets.token_hex(16))')"
  READ_TOKEN="$("$VENV/bin/python" -c 'import secrets; print("read-" + secrets.token_hex(16))')"
  warn_if_spec_differs
  start_server --admin-token "$TOKEN" --read-token "$READ_TOKEN" --workers 1
  BASE="$BASE_URL"
fi

AUTH=()
[ -z "$TOKEN" ] || AUTH=(-H "Authorization: Bearer $TOKEN")

# --max-time bounds the run; timeout is a backstop for a phase that overruns it.
status=0
timeout --signal=INT --kill-after=30 "$((SECONDS_BUDGET + 180))" \
  "$VENV/bin/schemathesis" --config-file "$REPO/scripts/schemathesis.toml" run "$SPEC" \
  --url "$BASE" \
  "${AUTH[@]}" \
  --checks all \
  --max-time "$SECONDS_BUDGET" \
  --seed "$SEED" \
  --workers 1 \
  --request-timeout 60 \
  --no-color \
  --report junit,ndjson \
  --report-dir "$REPORT_DIR" \
  "${EXTRA[@]}" || status=$?

echo "reports in $REPORT_DIR" >&2
if [ "$status" = 124 ]; then
  echo "FAIL schemathesis: overran its time budget by 180 s" >&2
fi
if [ "$status" != 0 ] && [ -n "$SERVER_DIR" ]; then
  grep -E ' (ERROR|WARN) ' "$SERVER_DIR/server.log" | tail -n 20 >&2 || true
fi
exit "$status"
