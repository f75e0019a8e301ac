#!/usr/bin/env bash
# The fuzzer's run of docs/service.md ("Hardening"): schemathesis over every operation of a running server's
# /openapi.json, with the instructor's token, a roster student's token and none; then the server's 5xx lines
# and tracebacks. schemathesis is not a dependency: give its command in SCHEMATHESIS (a venv of its own).
#   bench/fuzz.sh embedded|redis PORT      (N1 N2 N3: cases per operation for the three tokens; 60 150 80)
set -u
cd "$(dirname "$0")/.."
BACKEND=${1:?embedded or redis}; PORT=${2:?a free port}; ST=${SCHEMATHESIS:-schemathesis}
D=$(mktemp -d /tmp/fuzz-$BACKEND.XXXX)
export TRACER_INSTRUCTOR_TOKEN=fuzz-instructor-token-0123456789
EXTRA=()
REDIS_PID=""
if [ "$BACKEND" = redis ]; then
    redis-server --port $((PORT + 1)) --bind 127.0.0.1 --save "" --appendonly no --daemonize yes \
        --pidfile "$D/redis.pid" --logfile "$D/redis.log"
    for _ in $(seq 50); do [ -s "$D/redis.pid" ] && break; sleep 0.1; done
    REDIS_PID=$(cat "$D/redis.pid")
    EXTRA=(--redis "redis://127.0.0.1:$((PORT + 1))/0")
fi
.venv/bin/python -m server --port "$PORT" --data-dir "$D/data" "${EXTRA[@]}" > "$D/server.log" 2>&1 &
SERVER=$!
trap 'kill $SERVER 2>/dev/null; wait $SERVER 2>/dev/null; [ -n "$REDIS_PID" ] && kill $REDIS_PID' EXIT
S=http://127.0.0.1:$PORT
for _ in $(seq 120); do curl -sf "$S/api/health" > /dev/null && break; sleep 1; done
AID=$(.venv/bin/python -m server.course publish --server "$S" --deadline 2099-01-01T00:00:00Z \
    scenes/grading/assignment.json | head -1)
printf 'id,name,email\ns1,Student One,s1@example.edu\n' |
    curl -s -X POST -H "Authorization: Bearer $TRACER_INSTRUCTOR_TOKEN" -H "Content-Type: text/csv" \
        --data-binary @- "$S/api/assignments/$AID/roster" > "$D/roster.json"
STUDENT=$(.venv/bin/python -c "import json, sys; print(json.load(open(sys.argv[1]))['students'][0]['token'])" \
    "$D/roster.json")
run() { "$ST" run "$S/openapi.json" -c not_a_server_error --request-timeout 30 --max-failures 50 "$@"; }
run -n "${N1:-60}" -H "Authorization: Bearer $TRACER_INSTRUCTOR_TOKEN" > "$D/instructor.log" 2>&1
run -n "${N2:-150}" -H "Authorization: Bearer $STUDENT" > "$D/student.log" 2>&1
run -n "${N3:-80}" > "$D/anonymous.log" 2>&1
for who in instructor student anonymous; do
    echo "$who: $(grep -A1 '^Test cases:' "$D/$who.log" | tail -1 | xargs)"
done
echo "5xx answers in the server's log: $(grep -cE '" 5[0-9][0-9] ' "$D/server.log")" \
    "($(grep -E '" 5[0-9][0-9] ' "$D/server.log" | grep -oE '(GET|POST|PUT|DELETE) [^ ?]+' | sort | uniq -c | xargs))"
echo "tracebacks: $(grep -c Traceback "$D/server.log"); logs in $D"
