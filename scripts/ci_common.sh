# Shared helpers of scripts/client_flow.sh and scripts/schemathesis.sh (sourced, not run).
#
#   ensure_venv PIP_SPEC...   create $COHORTFORGE_VENV when missing, pip-install the specs
#   start_server [FLAGS...]   start $BIN on a free loopback port with a temporary database;
#                             sets BASE_URL, SERVER_PID, SERVER_DIR
#   stop_server               stop it (call from the caller's EXIT trap)
#   warn_if_spec_differs      warn when `$BIN openapi` is not openapi/openapi.json
#
# Environment: COHORTFORGE_VENV (default ${TMPDIR:-/tmp}/cohortforge-venv),
# COHORTFORGE_BIN (default the debug build in CARGO_TARGET_DIR, else in the checkout's target/),
# OPENAPI_SPEC (the document checked, default openapi/openapi.json).

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${COHORTFORGE_VENV:-${TMPDIR:-/tmp}/cohortforge-venv}"
SPEC="${OPENAPI_SPEC:-$REPO/openapi/openapi.json}"
BIN="${COHORTFORGE_BIN:-${CARGO_TARGET_DIR:-$REPO/target}/debug/cohortforge}"
SERVER_PID=""
SERVER_DIR=""
BASE_URL=""

ensure_venv() {
  if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install --quiet --upgrade pip
  fi
  "$VENV/bin/pip" install --quiet "$@"
}

stop_server() {
  if [ -n "$SERVER_PID" ] && kill -0 "$SERVER_PID" 2>/dev/null; then
    kill -INT "$SERVER_PID" 2>/dev/null || true
    for _ in $(seq 50); do kill -0 "$SERVER_PID" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$SERVER_PID" 2>/dev/null || true
    wait "$SERVER_PID" 2>/dev/null || true
  fi
  SERVER_PID=""
  if [ -n "$SERVER_DIR" ] && [ -z "${KEEP_TMP:-}" ]; then
    rm -rf "$SERVER_DIR"
  fi
}

start_server() {
  if [ ! -x "$BIN" ]; then
    echo "no cohortforge binary at $BIN (build it, or set COHORTFORGE_BIN)" >&2
    return 1
  fi
  SERVER_DIR="$(mktemp -d "${TMPDIR:-/tmp}/cohortforge-ci.XXXXXX")"
  local port
  port="$("$VENV/bin/python" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
  BASE_URL="http://127.0.0.1:$port"
  "$BIN" serve --bind "127.0.0.1:$port" --database "$SERVER_DIR/cohortforge.db" "$@" \
    >"$SERVER_DIR/server.log" 2>&1 &
  SERVER_PID=$!
  # The liveness probe is GET /healthz (src/api/ops.rs); it needs no token.
  for _ in $(seq 300); do
    if curl -sf -o /dev/null "$BASE_URL/healthz"; then
      echo "server $BIN up at $BASE_URL (pid $SERVER_PID, log $SERVER_DIR/server.log)" >&2
      return 0
    fi
    if ! kill -0 "$SERVER_PID" 2>/dev/null; then
      echo "server exited early:" >&2
      cat "$SERVER_DIR/server.log" >&2
      return 1
    fi
    sleep 0.2
  done
  echo "server did not answer /healthz within 60 s" >&2
  return 1
}

# Warns when the binary serves another OpenAPI document than the checked-in one (the checks
# test the checked-in file against the binary's behaviour; a stale build skews them).
warn_if_spec_differs() {
  if ! "$BIN" openapi 2>/dev/null | "$VENV/bin/python" -c '
import json, sys
served = json.load(sys.stdin)
sys.exit(served != json.load(open(sys.argv[1])))' "$SPEC"; then
    echo "WARNING: $BIN openapi differs from $SPEC (stale build or spec)" >&2
  fi
}
