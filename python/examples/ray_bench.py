"""Ray's cost per task against the work of a unit, and the speed-up of
`tune` and of a rheology calibration on 1 and 2 raylets, measured; then
the speed-up on 8-64 workers simulated from those measured costs.

    python python/examples/ray_bench.py [--candidates 8 --plants 4] [--json F]

(docs/benchmarks.md, issue 33, has the figures and what they mean.)

Measured here, on local clusters of `ray start` processes (LocalCluster):
- Ray's overhead per task: 400 empty tasks fanned out and gathered (the
  time per task), and one task's round trip (median of 50);
- the work of one tune candidate (its plants' runs) and of one rheology
  evaluation, timed in this process;
- a `tune` and a rheology calibration on 1 raylet and on 2 raylets of one
  CPU each, against the same sweep run unit after unit in this process.

Simulated (list scheduling, the model in `simulate`): a sweep's units in
index order go to the first free of W workers, each unit costing its
work plus the per-task overhead; a GA generation is a barrier (its
children scored before the next selection); the driver's reduction
(tune's held-out runs) is added after. The model leaves out the network
between machines and a worker's start-up (measured here as part of the
first tasks, a one-off of about a second per worker).
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

import ray

import softjoint
from softjoint import ray_sweep

REPO = Path(__file__).resolve().parents[2]


@ray.remote
def _noop(x):
    return x


def task_overhead_s(n: int = 400):
    """(time per task fanned out, median round trip of one task)."""
    ray.get([_noop.remote(i) for i in range(20)])  # workers started
    t = time.perf_counter()
    ray.get([_noop.remote(i) for i in range(n)])
    per_task = (time.perf_counter() - t) / n
    trips = []
    for i in range(50):
        t = time.perf_counter()
        ray.get(_noop.remote(i))
        trips.append(time.perf_counter() - t)
    return per_task, statistics.median(trips)


def timed(f):
    t = time.perf_counter()
    out = f()
    return time.perf_counter() - t, out


def measure(args):
    plant = softjoint.load_plant(REPO / "scenarios/identify/plant.toml")
    scen = str(REPO / "scenarios/rheology/small.toml")
    out = {}
    # Work per unit, in this process.
    sweep = softjoint.TuneSweep(plant, 2, args.plants, 1)
    out["tune_candidate_s"], _ = timed(lambda: sweep.run_unit(0, 0, 1))
    out["tune_run_s"] = out["tune_candidate_s"] / args.plants
    problem = softjoint.rheology_problem(scen, None, 4)
    genes = [[800.0, 5000.0, 9000.0, 0.45]] * 20
    t, _ = timed(lambda: problem.scores(genes))
    out["rheology_eval_small_s"] = t / len(genes)
    # The whole sweeps in this process (the reference for the speed-up).
    out["tune_serial_s"], want = timed(
        lambda: softjoint.tune(plant, args.candidates, args.plants, 1, unit=1))
    red = softjoint.TuneSweep(plant, args.candidates, args.plants, 1)
    units = [red.run_unit(*u) for u in red.units(1)]
    out["tune_reduce_s"], _ = timed(lambda: red.reduce(units))
    out["rheology_serial_s"], _ = timed(lambda: problem.calibrate("ga", args.evaluations, 3))
    for raylets in (1, 2):
        with ray_sweep.LocalCluster(raylets=raylets, cpus=1):
            per_task, trip = task_overhead_s()
            out[f"ray{raylets}_per_task_s"] = per_task
            out[f"ray{raylets}_round_trip_s"] = trip
            # One warm-up sweep (workers import softjoint, build the plants).
            ray_sweep.tune(plant, raylets, args.plants, 1)
            t, got = timed(lambda: ray_sweep.tune(plant, args.candidates, args.plants, 1))
            assert got == want, "the Ray sweep must give the local result"
            out[f"ray{raylets}_tune_s"] = t
            t, _ = timed(lambda: ray_sweep.rheology_calibrate(scen, None, 4, "ga",
                                                              args.evaluations, 3, unit=1))
            out[f"ray{raylets}_rheology_s"] = t
    return out


def makespan(durations, workers):
    """List scheduling: each unit, in order, to the first free worker."""
    free = [0.0] * workers
    for d in durations:
        k = min(range(workers), key=free.__getitem__)
        free[k] += d
    return max(free)


def simulate(m, workers=(1, 2, 4, 8, 16, 32, 64)):
    """Speed-up of the paper-sized sweeps from measured costs (the model
    in the module's docs). Costs per run/evaluation are the issue's
    release-build figures (tune 1,000 x 20 in 7 CPU-min: 21 ms a run;
    rheology 10,000 evaluations in 20 CPU-min: 0.12 s each); the task
    overhead is the 2-raylet figure measured here."""
    o = m["ray2_per_task_s"]
    run_s, eval_s = 7 * 60 / 20_000, 20 * 60 / 10_000
    rows = []
    for unit in (1, 2, 8):
        n_units = math.ceil(1000 / unit)
        work = [unit * 20 * run_s + o] * n_units
        serial = 1000 * 20 * run_s
        heldout = 2 * 20 * run_s / 2  # on the driver's 2 threads
        rows.append(("tune 1000x20", unit, [serial / (makespan(work, w) + heldout) for w in workers]))
    for unit in (1, 4):
        # GA: 50 first, then 40 children a generation; 10,000 evaluations.
        gens = [50] + [40] * ((10_000 - 50) // 40)
        serial = sum(gens) * eval_s
        sp = []
        for w in workers:
            t = sum(makespan([min(unit, g - a) * eval_s + o for a in range(0, g, unit)], w)
                    for g in gens)
            sp.append(serial / t)
        rows.append(("rheology GA 10,000", unit, sp))
    return workers, rows


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--candidates", type=int, default=8)
    p.add_argument("--plants", type=int, default=4)
    p.add_argument("--evaluations", type=int, default=200)
    p.add_argument("--json", help="write the measured figures here")
    a = p.parse_args()
    m = measure(a)
    for k, v in m.items():
        print(f"{k:28} {v:10.4f}")
    workers, rows = simulate(m)
    print("\nsimulated speed-up (workers: " + ", ".join(map(str, workers)) + ")")
    for name, unit, sp in rows:
        print(f"{name:22} unit {unit:2}: " + "  ".join(f"{s:5.1f}" for s in sp))
    if a.json:
        Path(a.json).write_text(json.dumps({"measured": m, "simulated": rows}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
