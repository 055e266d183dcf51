#!/usr/bin/env bash
# Throwaway PostgreSQL server on loopback for the service's PostgreSQL test pass.
#
#   eval "$(.ci/postgres.sh start)"   # installs Debian's postgresql if missing, starts a fresh
#                                     # cluster on 127.0.0.1:<free port>, prints
#                                     # `export SNAPWARN_TEST_PG_URL=...` (and PGDATA_DIR)
#   .ci/postgres.sh stop              # stops it and deletes the cluster
#
# The cluster lives in a temporary directory owned by the `postgres` user (initdb refuses to run
# as root), trusts connections from loopback only, and is deleted by `stop`. Messages go to
# stderr so that stdout can be eval'ed.
set -euo pipefail

STATE_FILE="${SNAPWARN_PG_STATE:-/tmp/snapwarn-ci-postgres.state}"
DB_NAME="${SNAPWARN_PG_DB:-snapwarn_test}"

log() { echo "postgres.sh: $*" >&2; }

pg_bindir() {
    local d
    d=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1 || true)
    if [[ -n "$d" && -x "$d/initdb" ]]; then echo "$d"; return 0; fi
    return 1
}

install_pg() {
    if pg_bindir >/dev/null; then return 0; fi
    log "installing Debian's postgresql package"
    local SUDO=""
    if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq >&2
    $SUDO apt-get install -y -qq --no-install-recommends postgresql >&2
    pg_bindir >/dev/null || { log "no initdb after installing postgresql"; exit 1; }
}

# Run a command as the cluster owner: `postgres` when we are root, ourselves otherwise.
as_owner() {
    if [[ $(id -u) -eq 0 ]]; then
        runuser -u postgres -- "$@"
    else
        "$@"
    fi
}

free_port() {
    python3 - <<'EOF'
import socket
s = socket.socket()
s.bind(("127.0.0.1", 0))
print(s.getsockname()[1])
s.close()
EOF
}

start() {
    install_pg
    local bindir dir port
    bindir=$(pg_bindir)
    if [[ -f "$STATE_FILE" ]]; then
        log "a previous cluster is recorded in $STATE_FILE; stopping it first"
        stop || true
    fi
    dir=$(mktemp -d /tmp/snapwarn-pg.XXXXXX)
    chmod 755 "$dir"
    if [[ $(id -u) -eq 0 ]]; then chown postgres:postgres "$dir"; fi
    port=$(free_port)
    as_owner "$bindir/initdb" -D "$dir/data" -U postgres --auth=trust --encoding=UTF8 \
        --locale=C.UTF-8 >"$dir/initdb.log" 2>&1 \
        || { cat "$dir/initdb.log" >&2; exit 1; }
    as_owner "$bindir/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 \
        -o "-c listen_addresses=127.0.0.1 -p $port -k $dir -c fsync=off" start >&2 \
        || { cat "$dir/server.log" >&2; exit 1; }
    as_owner "$bindir/createdb" -h 127.0.0.1 -p "$port" -U postgres "$DB_NAME"
    printf 'DIR=%s\nPORT=%s\nBINDIR=%s\n' "$dir" "$port" "$bindir" >"$STATE_FILE"
    log "PostgreSQL $("$bindir/postgres" --version | awk '{print $3}') on 127.0.0.1:$port ($dir)"
    echo "export SNAPWARN_TEST_PG_URL=postgresql+psycopg://postgres@127.0.0.1:$port/$DB_NAME"
    echo "export SNAPWARN_PG_DIR=$dir"
}

stop() {
    if [[ ! -f "$STATE_FILE" ]]; then log "nothing to stop"; return 0; fi
    # shellcheck disable=SC1090
    source "$STATE_FILE"
    as_owner "$BINDIR/pg_ctl" -D "$DIR/data" -m fast -w stop >&2 || true
    rm -rf "$DIR" "$STATE_FILE"
    log "stopped and removed $DIR"
}

case "${1:-start}" in
    start) start ;;
    stop) stop ;;
    *) echo "usage: $0 [start|stop]" >&2; exit 2 ;;
esac
