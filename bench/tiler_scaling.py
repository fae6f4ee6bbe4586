#!/usr/bin/env python3
"""Scaling table from `stipple tile --stats` JSON files (bench/tiler.sh --threads T).

usage: tiler_scaling.py T PREDICT ONE.json... -- MANY.json...
ONE: runs at 1 thread, MANY: runs at T threads; the median run of each (by wall time) is used
per phase. Serial fraction by the Karp-Flatt metric from the two: with speedup S = W1 / WT,
e = (1/S - 1/T) / (1 - 1/T); Amdahl then predicts 1 / (e + (1 - e) / P) on P threads.
On a shared machine the wall times carry the other processes' load, so the table also gives the
serial fraction sampled in the runs at T threads: with a = the time at most one thread was
runnable (running or ready to run) and b = the rest, run by T threads, the work at one thread is
a + T b and the serial fraction a / (a + T b).
"""
import json
import statistics
import sys


def load(paths):
    return [json.load(open(p)) for p in paths]


def serial(w1, wt, t):
    if w1 <= 0 or wt <= 0:
        return float("nan")
    return (wt / w1 - 1 / t) / (1 - 1 / t)


def amdahl(e, p):
    return 1 / (e + (1 - e) / p)


def main():
    t, predict = int(sys.argv[1]), int(sys.argv[2])
    rest = sys.argv[3:]
    cut = rest.index("--")
    one, many = load(rest[:cut]), load(rest[cut + 1:])
    names = [p["name"] for p in one[0]["phases"]]

    def med(runs, name, key):
        vals = []
        for r in runs:
            for p in r["phases"]:
                if p["name"] == name:
                    vals.append(p[key] if key != "cpu" else p["user"] + p["sys"])
        return statistics.median(vals) if vals else 0.0

    w1_total = statistics.median(r["seconds"] for r in one)
    wt_total = statistics.median(r["seconds"] for r in many)
    points = one[0]["points"]
    print(f"{points} points; medians of {len(one)} runs at 1 thread and {len(many)} at {t}")
    print()
    print(f"| phase | wall 1 thr | wall {t} thr | CPU 1 thr | CPU {t} thr | speedup | "
          f"serial fraction of phase | share of job's serial fraction | one thread at {t} (sampled) | "
          f"sampled serial fraction of phase | sampled share of job's |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
    work = {}
    for n in names:
        a, w = med(many, n, "oneThread"), med(many, n, "wall")
        work[n] = (a, a + t * max(0.0, w - a))
    total_work = sum(v[1] for v in work.values())
    for n in names:
        w1, wt = med(one, n, "wall"), med(many, n, "wall")
        c1, ct = med(one, n, "cpu"), med(many, n, "cpu")
        e = serial(w1, wt, t)
        share = e * w1 / w1_total if w1_total > 0 else 0
        sp = w1 / wt if wt > 0 else float("nan")
        print(f"| {n} | {w1:.3f} s | {wt:.3f} s | {c1:.2f} s | {ct:.2f} s | {sp:.2f} | "
              f"{e * 100:.1f}% | {share * 100:.2f}% | {med(many, n, 'oneThread'):.3f} s | "
              f"{work[n][0] / work[n][1] * 100 if work[n][1] > 0 else 0:.1f}% | "
              f"{work[n][0] / total_work * 100:.2f}% |")
    e = serial(w1_total, wt_total, t)
    c1 = statistics.median(sum(p["user"] + p["sys"] for p in r["phases"]) for r in one)
    ct = statistics.median(sum(p["user"] + p["sys"] for p in r["phases"]) for r in many)
    print(f"| **job** | {w1_total:.3f} s | {wt_total:.3f} s | {c1:.2f} s | {ct:.2f} s | "
          f"{w1_total / wt_total:.2f} | {e * 100:.1f}% | | | | |")
    es = sum(v[0] for v in work.values()) / total_work
    print()
    print(f"Throughput: {points / w1_total / 1e6:.2f} M points/s at 1 thread, "
          f"{points / wt_total / 1e6:.2f} at {t}.")
    print(f"Serial fraction of the job: {e * 100:.1f}% (goal <= 3%). Amdahl on {predict} threads: "
          f"{amdahl(e, predict):.2f}x, {points / w1_total * amdahl(e, predict) / 1e6:.1f} M points/s "
          f"at this machine's single-thread speed.")
    print(f"Sampled serial fraction (runs at {t} threads): {es * 100:.1f}%. Amdahl on {predict} "
          f"threads: {amdahl(es, predict):.2f}x, "
          f"{points / w1_total * amdahl(es, predict) / 1e6:.1f} M points/s.")
    print()
    print("| step | thread s at 1 thr | thread s at {0} thr | CPU s at 1 thr | CPU s at {0} thr |".format(t))
    print("|---|--:|--:|--:|--:|")
    for s in one[0]["steps"]:
        def ms(runs, key):
            return statistics.median(r["steps"][s][key] for r in runs)
        print(f"| {s} | {ms(one, 'threadSeconds'):.3f} | {ms(many, 'threadSeconds'):.3f} | "
              f"{ms(one, 'cpu'):.3f} | {ms(many, 'cpu'):.3f} |")


main()
