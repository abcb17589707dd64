#!/usr/bin/env bash
# Generates a Python client from openapi/openapi.json with openapi-python-client and runs
# the README quickstart through it (scripts/client_flow.py): one `ok <step>` or
# `FAIL <step>: <reason>` line per step; exits non-zero when a step fails.
#
# Usage:
#   scripts/client_flow.sh --start [FLOW OPTIONS]            # starts its own server
#   scripts/client_flow.sh --base-url URL [--token T] [FLOW OPTIONS]
# FLOW OPTIONS go to client_flow.py, e.g. --allow-gaps (generator gaps reported as ok),
# --fit-params JSON, --cohort-size N, --workdir DIR.
#
# Environment: COHORTFORGE_VENV (venv, default ${TMPDIR:-/tmp}/cohortforge-venv),
# COHORTFORGE_BIN (binary for phantoms and --start, default the debug build),
# OPENAPI_PYTHON_CLIENT (pip spec, default openapi-python-client==0.29.1), KEEP_TMP=1 (keep
# the generated client, downloads and server log).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/ci_common.sh"

START=0
BASE=""
TOKEN=""
PASS=()
while [ $# -gt 0 ]; do
  case "$1" in
    --start) START=1; shift ;;
    --base-url) BASE="$2"; shift 2 ;;
    --token) TOKEN="$2"; shift 2 ;;
    --cohortforge) BIN="$2"; shift 2 ;;
    -h|--help) sed -n '2,/^set /{/^#/p}' "$0"; exit 0 ;;
    *) PASS+=("$1"); shift ;;
  esac
done
if [ "$START" = 0 ] && [ -z "$BASE" ]; then
  echo "give --start or --base-url URL" >&2
  exit 2
fi

WORK="$(mktemp -d "${TMPDIR:-/tmp}/cohortforge-client.XXXXXX")"
cleanup() { stop_server; [ -n "${KEEP_TMP:-}" ] || rm -rf "$WORK"; }
trap cleanup EXIT

ensure_venv "${OPENAPI_PYTHON_CLIENT:-openapi-python-client==0.29.1}"
echo "openapi-python-client $("$VENV/bin/pip" show openapi-python-client | sed -n 's/^Version: //p')" >&2

# Generate the client; its warnings (dropped content types, ...) are findings: summarise them.
"$VENV/bin/openapi-python-client" generate --path "$SPEC" \
  --output-path "$WORK/client" --meta setup >"$WORK/generate.log" 2>&1 || {
  cat "$WORK/generate.log" >&2
  echo "FAIL generate: openapi-python-client could not generate a client" >&2
  exit 1
}
echo "generator warnings:" >&2
awk '/^WARNING parsing/ {op = $3 " " $4; getline; getline; print "  " op ": " $0}' \
  "$WORK/generate.log" | sed 's/<openapi_python_client[^>]*> //' | sort -u >&2
"$VENV/bin/pip" install --quiet --force-reinstall --no-deps "$WORK/client"
"$VENV/bin/pip" install --quiet "$WORK/client"  # its dependencies (httpx, attrs)

ARGS=(--cohortforge "$BIN" --workdir "$WORK/flow")
if [ "$START" = 1 ]; then
  warn_if_spec_differs
  start_server
  ARGS+=(--base-url "$BASE_URL")
else
  ARGS+=(--base-url "$BASE")
  [ -z "$TOKEN" ] || ARGS+=(--token "$TOKEN")
fi

status=0
"$VENV/bin/python" "$REPO/scripts/client_flow.py" "${ARGS[@]}" "${PASS[@]}" || status=$?
if [ "$status" != 0 ] && [ -n "$SERVER_DIR" ]; then
  echo "--- last server log lines ---" >&2
  tail -n 20 "$SERVER_DIR/server.log" >&2
fi
exit "$status"
