#!/usr/bin/env bash
# bench/soak.sh MINUTES: a streaming soak. A tileset (`stipple generate` + `stipple tile`) is served
# by nginx on 127.0.0.1 with faults injected per request (split_clients on the random request id):
# FAULT_ERR% of content requests answer 500, FAULT_TRUNC% get the file cut in half, FAULT_SLOW%
# come through a location throttled to 32 KiB/s. `stipple bench stream` flies its scripted
# camera path (an orbit while the field of view zooms) over it for MINUTES, under a small resident
# tile budget (MEMORY_MB, default 8) and a fine screen-space error (MAX_SSE, default 2 pixels) so
# that tiles are evicted and fetched again all along.
# The process's RSS is sampled every second (samples.csv in the work directory); at the end the
# run fails if it crashed, if the peak resident tile bytes passed the budget, or if RSS grew over
# the last half of the run (least-squares slope x half the duration > max(16 MiB, 5% of mean)).
#   bench/soak.sh 60                      the issue's hour
#   STIPPLE=build/stipple POINTS=3000000 bench/soak.sh 5
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
minutes=${1:?usage: bench/soak.sh MINUTES}
stipple=${STIPPLE:-$root/build/stipple}
points=${POINTS:-2000000}
memory_mb=${MEMORY_MB:-8}
max_sse=${MAX_SSE:-2}
err=${FAULT_ERR:-5} trunc=${FAULT_TRUNC:-5} slow=${FAULT_SLOW:-10}
work=${SOAK_DIR:-$root/bench/soak-out}
nginx=$(command -v nginx || echo /usr/sbin/nginx)
[[ -x "$nginx" ]] || { echo "soak.sh: nginx not found (Debian nginx-light)" >&2; exit 2; }
[[ -x "$stipple" ]] || { echo "soak.sh: $stipple not found (scripts/setup.sh builds it)" >&2; exit 2; }

rm -rf "$work/www" "$work/tmp" "$work"/*.log && mkdir -p "$work/www" "$work/tmp"
if [[ ! -f "$work/cloud-$points.las" ]]; then
  "$stipple" generate -o "$work/cloud-$points.las" -n "$points" >/dev/null
fi
"$stipple" tile "$work/cloud-$points.las" -o "$work/www/tiles" --max-node-points 20000 >/dev/null
# Truncated copies of every content file, served in place of the real one.
(cd "$work/www/tiles" && find . -type f ! -name '*.json' | while read -r f; do
  mkdir -p "$work/www/trunc/$(dirname "$f")"
  head -c $(($(stat -c %s "$f") / 2)) "$f" >"$work/www/trunc/$f"
done)
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
cat >"$work/nginx.conf" <<EOF
daemon off;
user $(id -un);
worker_processes 1;
error_log $work/error.log;
pid $work/nginx.pid;
events { worker_connections 256; }
http {
  access_log $work/access.log;
  client_body_temp_path $work/tmp; proxy_temp_path $work/tmp; fastcgi_temp_path $work/tmp;
  uwsgi_temp_path $work/tmp; scgi_temp_path $work/tmp;
  types { application/json json; application/octet-stream pnts glb subtree; }
  split_clients "\${request_id}" \$fault { $err% err; $trunc% trunc; $slow% slow; * ok; }
  server {
    listen 127.0.0.1:$port;
    root $work/www;
    location = /tiles/tileset.json { }
    location /tiles/ {
      if (\$fault = err) { return 500; }
      if (\$fault = trunc) { rewrite ^/tiles/(.*)\$ /trunc/\$1 last; }
      if (\$fault = slow) { rewrite ^/tiles/(.*)\$ /slow/\$1 last; }
    }
    location /trunc/ { internal; }
    location /slow/ { internal; alias $work/www/tiles/; limit_rate 32k; }
  }
}
EOF
"$nginx" -p "$work/" -c "$work/nginx.conf" &
nginx_pid=$!
trap 'kill $nginx_pid 2>/dev/null || true' EXIT
for _ in $(seq 50); do curl -sf -o /dev/null "http://127.0.0.1:$port/tiles/tileset.json" && break; sleep 0.1; done
url="http://127.0.0.1:$port/tiles/tileset.json"
common=(--width 960 --height 540 --memory-mb "$memory_mb" --max-sse "$max_sse")

# Warm-up: frames per second on this machine, to size the run.
"$stipple" bench stream "$url" "${common[@]}" --frames 120 --json "$work/warmup.json" \
  >"$work/warmup.log" 2>&1 || { echo "FAIL: warm-up run"; tail -n 20 "$work/warmup.log"; exit 1; }
fps=$(python3 -c "import json; print(json.load(open('$work/warmup.json'))['fps']['average'])")
# The warm-up's average includes the first loads: the long run is faster, hence the 1.25.
frames=$(python3 -c "print(max(120, min(1000000, int(1.25 * $fps * $minutes * 60))))")
echo "soak: $minutes min, $frames frames at ~$fps FPS (warm-up), budget $memory_mb MiB, faults: $err% 500, $trunc% truncated, $slow% throttled"

"$stipple" bench stream "$url" "${common[@]}" --frames "$frames" --json "$work/soak.json" \
  >"$work/soak.log" 2>&1 &
pid=$!
start=$(date +%s.%N)
echo "seconds,rss_kib" >"$work/samples.csv"
while kill -0 "$pid" 2>/dev/null; do
  rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
  [[ -n "$rss" ]] && echo "$(echo "$(date +%s.%N) - $start" | bc),$rss" >>"$work/samples.csv"
  sleep 1
done
rc=0
wait "$pid" || rc=$?
requests=$(wc -l <"$work/access.log")
codes=$(awk '{print $9}' "$work/access.log" | sort | uniq -c | tr '\n' ' ')
echo "requests: $requests (status: $codes)"
if [[ $rc -ne 0 ]]; then
  echo "FAIL: bench stream exited $rc"
  tail -n 20 "$work/soak.log"
  exit 1
fi
tail -n 3 "$work/soak.log"
python3 - "$work" <<'PY'
import csv, json, sys
work = sys.argv[1]
j = json.load(open(f"{work}/soak.json"))
rows = [(float(r["seconds"]), int(r["rss_kib"]) / 1024.0) for r in csv.DictReader(open(f"{work}/samples.csv"))]
ok = True
print(f"loads {j['loads']}, evictions {j['evictions']}, errors {j['errors']}; "
      f"peak resident {j['peak_resident_bytes'] / 2**20:.1f} MiB of {j['memory_budget'] / 2**20:.1f}")
if j["peak_resident_bytes"] > j["memory_budget"]:
    print("FAIL: resident tile bytes passed the budget"); ok = False
half = [r for r in rows if r[0] >= rows[-1][0] / 2] if rows else []
if len(half) >= 3:
    n = len(half); mx = sum(t for t, _ in half) / n; my = sum(m for _, m in half) / n
    slope = sum((t - mx) * (m - my) for t, m in half) / max(1e-9, sum((t - mx) ** 2 for t, _ in half))
    span = half[-1][0] - half[0][0]
    growth = slope * span
    limit = max(16.0, 0.05 * my)
    print(f"RSS: {len(rows)} samples, first {rows[0][1]:.0f} MiB, max {max(m for _, m in rows):.0f} MiB, "
          f"last half mean {my:.0f} MiB, slope {slope * 60:.2f} MiB/min ({growth:+.1f} MiB over "
          f"{span:.0f} s, limit {limit:.0f})")
    if growth > limit:
        print("FAIL: RSS grows over the last half"); ok = False
else:
    print("RSS: too few samples for a slope")
sys.exit(0 if ok else 1)
PY
