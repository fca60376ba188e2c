#!/usr/bin/env bash
# From a compute request to a pullable part in `ves view SCENE.toml` (default: the mould), cold (an empty
# mesh cache) and with only the supports changed (mesh cached), and the haptic loop's missed
# deadlines in each session that ran beside a compute. Prints the client's JSON, then the
# server's statistics (`sessions`: one entry per session, the compute that replaced it ran
# during its last seconds).
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:-cases/mould/scene.toml}
cache=$(mktemp -d)
trap 'rm -rf "$cache"' EXIT
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
XDG_CACHE_HOME=$cache "${VES:-target/release/ves}" view "$scene" --port "$port" --duration 900 --json > "$cache/server.out" &
server=$!
sleep 1
status=0
NODE_NO_WARNINGS=1 node --experimental-websocket bench/setup.mjs "http://127.0.0.1:$port/" || status=$?
kill -INT "$server"
wait "$server" || true
[ "$status" -eq 0 ] || { echo "the client's run failed (status $status)" >&2; exit "$status"; }
tail -1 "$cache/server.out"
