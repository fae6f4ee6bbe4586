#!/usr/bin/env bash
# bench/soak.sh MINUTES: a streaming soak. A tileset (`stipple generate` + `stipple tile`) is served
# by nginx on 127.0.0.1 with faults injected per request (split_clients on the random request id):
# FAULT_ERR% of content requests answer 500, FAULT_TRUNC% get the file cut in half, FAULT_SLOW%
# come through a location throttled to 32 KiB/s. `stipple bench stream` flies its scripted
# camera path (an orbit while the field of view zooms) over it for MINUTES, under a small resident
# tile budget (MEMORY_MB, default 8) and a fine screen-space error (MAX_SSE, default 2 pixels) so
# that tiles are evicted and fetched again all along (one orbit and two zooms a minute).
# `bench stream --samples` writes a row every second (samples.csv in the work directory): RSS,
# resident tile bytes, the tiles' GPU bytes as the allocators account them, loads, evictions,
# errors. At the end the run fails if it crashed, if the resident tile bytes passed the budget in
# any second (or at their peak), if the GPU bytes passed theirs (GPU_MB, default MEMORY_MB: the
# GPU holds a compacted copy of resident tiles) or their reserved buffers, or if RSS grew over the
# last half of the run (least-squares slope x half the duration > max(16 MiB, 5% of mean)).
#   bench/soak.sh 60                      the issue's hour
#   STIPPLE=build/stipple POINTS=3000000 bench/soak.sh 5
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
minutes=${1:?usage: bench/soak.sh MINUTES}
stipple=${STIPPLE:-$root/build/stipple}
points=${POINTS:-2000000}
memory_mb=${MEMORY_MB:-8}
gpu_mb=${GPU_MB:-$memory_mb}
# The flight: an orbit a minute (TURNS over the run), zooming in and out every half minute
# (ZOOM_CYCLES), so that tiles are fetched and evicted all along, not only in the first minutes.
turns=${TURNS:-$minutes}
zooms=${ZOOM_CYCLES:-$((2 * minutes))}
max_sse=${MAX_SSE:-2}
err=${FAULT_ERR:-5} trunc=${FAULT_TRUNC:-5} slow=${FAULT_SLOW:-10}
work=${SOAK_DIR:-$root/bench/soak-out}
nginx=$(command -v nginx || echo /usr/sbin/nginx)
[[ -x "$nginx" ]] || { echo "soak.sh: nginx not found (Debian nginx-light)" >&2; exit 2; }
[[ -x "$stipple" ]] || { echo "soak.sh: $stipple not found (scripts/setup.sh builds it)" >&2; exit 2; }

rm -rf "$work/www" "$work/tmp" "$work"/*.log "$work"/*.json "$work/samples.csv" && mkdir -p "$work/www" "$work/tmp"
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
  log_format soak '\$remote_addr - - [\$time_local] "\$request" \$status \$body_bytes_sent \$fault';
  access_log $work/access.log soak;
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
common=(--width 960 --height 540 --memory-mb "$memory_mb" --max-sse "$max_sse" --turns "$turns"
  --zoom-cycles "$zooms")

# Warm-up: frames per second on this machine, to size the run.
"$stipple" bench stream "$url" "${common[@]}" --frames 120 --json "$work/warmup.json" \
  >"$work/warmup.log" 2>&1 || { echo "FAIL: warm-up run"; tail -n 20 "$work/warmup.log"; exit 1; }
fps=$(python3 -c "import json; print(json.load(open('$work/warmup.json'))['fps']['average'])")
# With --duration the path runs by the clock and ends the run at MINUTES: the frames are only a
# cap (the most bench stream takes), so that a run that speeds up (a machine that gets quieter
# than at the warm-up) still lasts the whole time.
frames=1000000
echo "soak: $minutes min at ~$fps FPS (warm-up), $turns turns, $zooms zooms, budget $memory_mb MiB, faults: $err% 500, $trunc% truncated, $slow% throttled"

"$stipple" bench stream "$url" "${common[@]}" --frames "$frames" --json "$work/soak.json" \
  --duration $((minutes * 60)) --samples "$work/samples.csv" >"$work/soak.log" 2>&1 &
pid=$!
rc=0
wait "$pid" || rc=$?
requests=$(wc -l <"$work/access.log")
codes=$(awk '{print $9}' "$work/access.log" | sort | uniq -c | tr '\n' ' ')
faults=$(awk '$7 != "/tiles/tileset.json" {print $11}' "$work/access.log" | sort | uniq -c | tr '\n' ' ')
echo "requests: $requests (status: $codes; content requests by fault: $faults)"
if [[ $rc -ne 0 ]]; then
  echo "FAIL: bench stream exited $rc"
  tail -n 20 "$work/soak.log"
  exit 1
fi
tail -n 3 "$work/soak.log"
python3 "$root/bench/soak_check.py" "$work" "$gpu_mb"
