#!/usr/bin/env bash
# A throwaway PostgreSQL cluster for tests and benchmarks: a new data directory under a
# temporary directory, listening on a free loopback port with trust authentication.
#
#   eval "$(scripts/postgres_throwaway.sh start)"   # sets COHORTFORGE_TEST_POSTGRES, PG_THROWAWAY_DIR
#   scripts/postgres_throwaway.sh stop "$PG_THROWAWAY_DIR"
#
# Installs Debian's postgresql when no initdb is found. As root, the cluster runs as the
# `postgres` user (PostgreSQL refuses to run as root).
set -euo pipefail

find_bin() {
  local name=$1
  if command -v "$name" >/dev/null; then command -v "$name"; return; fi
  local found
  found=$(ls -d /usr/lib/postgresql/*/bin/"$name" 2>/dev/null | sort -V | tail -1 || true)
  [ -n "$found" ] && echo "$found"
}

as_owner() {
  if [ "$(id -u)" = 0 ]; then
    runuser -u postgres -- "$@"
  else
    "$@"
  fi
}

start() {
  if [ -z "$(find_bin initdb)" ] && command -v apt-get >/dev/null; then
    (apt-get install -y --no-install-recommends postgresql || \
      (apt-get update && apt-get install -y --no-install-recommends postgresql)) >/dev/null 2>&1 || true
  fi
  local initdb pg_ctl
  initdb=$(find_bin initdb || true)
  pg_ctl=$(find_bin pg_ctl || true)
  if [ -z "$initdb" ] || [ -z "$pg_ctl" ]; then
    echo "postgres_throwaway: no PostgreSQL server binaries (initdb, pg_ctl) could be found or installed" >&2
    exit 1
  fi
  local dir port
  dir=$(mktemp -d /tmp/cohortforge-pg.XXXXXX)
  port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  if [ "$(id -u)" = 0 ]; then chown postgres "$dir"; fi
  as_owner "$initdb" -D "$dir/data" -U postgres --auth=trust -E UTF8 >/dev/null
  as_owner "$pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 \
    -o "-c listen_addresses=127.0.0.1 -c port=$port -c unix_socket_directories=$dir -c max_connections=400" \
    start >/dev/null
  echo "export COHORTFORGE_TEST_POSTGRES=postgres://postgres@127.0.0.1:$port"
  echo "export PG_THROWAWAY_DIR=$dir"
}

stop() {
  local dir=${1:?give the directory printed by start}
  local pg_ctl
  pg_ctl=$(find_bin pg_ctl)
  as_owner "$pg_ctl" -D "$dir/data" -m fast -w stop >/dev/null || true
  rm -rf "$dir"
}

case "${1:-}" in
  start) start ;;
  stop) stop "${2:-}" ;;
  *) echo "usage: $0 start | stop DIR" >&2; exit 2 ;;
esac
