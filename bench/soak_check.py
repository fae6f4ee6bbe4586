#!/usr/bin/env python3
"""bench/soak_check.py WORK [GPU_MB]: the checks of bench/soak.sh over its work directory:
samples.csv (`bench stream --samples`, one row a second) and soak.json (the run's summary).
Also usable while a soak runs, or after it was cut short: without soak.json it reports and checks
the rows written so far. Exits 1 when a budget was exceeded in any second or RSS grew over the
last half of the run (least-squares slope x the half's span > max(16 MiB, 5% of its mean))."""
import csv, json, sys
import os
work = sys.argv[1]
rows = list(csv.DictReader(open(f"{work}/samples.csv")))
if not rows:
    print("FAIL: no samples"); sys.exit(1)
gpu_budget = (float(sys.argv[2]) * 2**20 if len(sys.argv) > 2
              else int(rows[0]["memory_budget"]))
ok = True
mib = lambda b: int(b) / 2**20
last = rows[-1]
if os.path.exists(f"{work}/soak.json"):
    j = json.load(open(f"{work}/soak.json"))
    print(f"run: {j['frames']} frames, {j['fps']['average']:.1f} FPS; loads {j['loads']}, "
          f"evictions {j['evictions']}, errors {j['errors']}; peak resident "
          f"{mib(j['peak_resident_bytes']):.1f} MiB of {mib(j['memory_budget']):.1f}")
    if j["peak_resident_bytes"] > j["memory_budget"]:
        print("FAIL: resident tile bytes passed the budget"); ok = False
else:
    print(f"run under way or cut short (no soak.json): so far loads {last['loads']}, "
          f"evictions {last['evictions']}, errors {last['errors']}")
over = [r for r in rows if int(r["resident_bytes"]) > int(r["memory_budget"])]
gpu_over = [r for r in rows if int(r["gpu_bytes"]) > gpu_budget
            or int(r["gpu_bytes"]) > int(r["gpu_reserved_bytes"])]
peak_gpu = max(rows, key=lambda r: int(r["gpu_bytes"]))
print(f"samples {len(rows)} over {float(rows[-1]['seconds']):.0f} s, {rows[-1]['frame']} frames; "
      f"resident tile bytes: max {max(mib(r['resident_bytes']) for r in rows):.2f} MiB of "
      f"{mib(rows[0]['memory_budget']):.1f}, over in {len(over)} samples; GPU bytes: max "
      f"{mib(peak_gpu['gpu_bytes']):.2f} MiB (reserved {mib(peak_gpu['gpu_reserved_bytes']):.2f}, "
      f"budget {gpu_budget / 2**20:.1f}), over in {len(gpu_over)} samples; "
      f"refused uploads {rows[-1]['refused_uploads']}")
if over:
    print(f"FAIL: resident tile bytes passed the budget at {over[0]['seconds']} s"); ok = False
if gpu_over:
    print(f"FAIL: GPU bytes passed their budget at {gpu_over[0]['seconds']} s"); ok = False
rss = [(float(r["seconds"]), mib(r["rss_bytes"])) for r in rows]
marks = sorted({min(len(rss) - 1, round(i * (len(rss) - 1) / 8)) for i in range(9)})
print("RSS (MiB) at " + ", ".join(f"{rss[i][0]:.0f} s: {rss[i][1]:.1f}" for i in marks))
half = [r for r in rss if r[0] >= rss[-1][0] / 2]
if len(half) >= 3:
    n = len(half); mx = sum(t for t, _ in half) / n; my = sum(m for _, m in half) / n
    slope = sum((t - mx) * (m - my) for t, m in half) / max(1e-9, sum((t - mx) ** 2 for t, _ in half))
    span = half[-1][0] - half[0][0]
    growth = slope * span
    limit = max(16.0, 0.05 * my)
    print(f"RSS: first {rss[0][1]:.0f} MiB, max {max(m for _, m in rss):.0f} MiB, "
          f"last half mean {my:.0f} MiB, slope {slope * 60:.2f} MiB/min ({growth:+.1f} MiB over "
          f"{span:.0f} s, limit {limit:.0f})")
    if growth > limit:
        print("FAIL: RSS grows over the last half"); ok = False
else:
    print("RSS: too few samples for a slope")
sys.exit(0 if ok else 1)
