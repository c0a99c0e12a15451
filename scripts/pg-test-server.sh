#!/usr/bin/env bash
# A throw-away PostgreSQL server for the history tests: a fresh cluster in a temporary folder,
# owned by a non-root user, listening on a free loopback port only, password (SCRAM) required
# over TCP. Nothing outside the folder is touched; `stop` removes it.
#
#   eval "$(bash scripts/pg-test-server.sh start)"   # exports KINECAL_TEST_PG and KINECAL_TEST_PG_DIR
#   bash scripts/pg-test-server.sh stop "$KINECAL_TEST_PG_DIR"
#
# Run as root, the cluster belongs to `nobody`; as another user, to that user. Needs the
# server binaries (Debian: `apt-get install postgresql`; found under /usr/lib/postgresql/*/bin).
set -euo pipefail

bindir() {
    local d
    for d in /usr/lib/postgresql/*/bin; do
        [ -x "$d/initdb" ] && { echo "$d"; return; }
    done
    command -v initdb >/dev/null 2>&1 && { dirname "$(command -v initdb)"; return; }
    echo "pg-test-server: no PostgreSQL server binaries (initdb) found" >&2
    return 1
}

as_owner() {
    if [ "$(id -u)" = 0 ]; then
        runuser -u nobody -- "$@"
    else
        "$@"
    fi
}

case "${1:-}" in
start)
    bin=$(bindir)
    dir=$(mktemp -d /tmp/kinecal-pg.XXXXXX)
    chmod 700 "$dir"
    [ "$(id -u)" = 0 ] && chown nobody "$dir"
    password=$(od -An -N12 -tx1 /dev/urandom | tr -d ' \n')
    printf '%s\n' "$password" >"$dir/pw"
    [ "$(id -u)" = 0 ] && chown nobody "$dir/pw"
    port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
    as_owner "$bin/initdb" -D "$dir/data" -U postgres --pwfile="$dir/pw" \
        --auth-host=scram-sha-256 --auth-local=trust -E UTF8 --no-locale >"$dir/initdb.log" 2>&1 ||
        { cat "$dir/initdb.log" >&2; exit 1; }
    rm -f "$dir/pw"
    as_owner "$bin/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 \
        -o "-c listen_addresses=127.0.0.1 -p $port -k $dir -c max_connections=200" start >/dev/null ||
        { cat "$dir/server.log" >&2; exit 1; }
    echo "export KINECAL_TEST_PG='postgres://postgres:$password@127.0.0.1:$port/postgres'"
    echo "export KINECAL_TEST_PG_DIR='$dir'"
    ;;
stop)
    dir=${2:?usage: pg-test-server.sh stop DIR}
    case "$dir" in /tmp/kinecal-pg.*) ;; *) echo "pg-test-server: not a test cluster: $dir" >&2; exit 1 ;; esac
    bin=$(bindir)
    if [ -f "$dir/data/postmaster.pid" ]; then
        as_owner "$bin/pg_ctl" -D "$dir/data" -m fast -w stop >/dev/null || true
    fi
    rm -rf "$dir"
    ;;
*)
    echo "usage: pg-test-server.sh start | stop DIR" >&2
    exit 2
    ;;
esac
