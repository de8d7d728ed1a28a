"""An identification's multi-start on Ray: the work of each start unit
against Ray's cost per task, `softjoint identify joint` on this machine
and with `--ray` on 1 and 2 raylets, and the mechanics stage on 1-64
workers simulated from the measured unit costs.

    python python/examples/identify_ray_bench.py [--duration-s 600] \\
        [--max-iterations 100] [--json F]

(docs/benchmarks.md, "Sweeps on Ray", has the figures.)

The log: `identify plan --joint 3d --duration-s D` recorded by `sim
--excite` on the default 3D joint. Measured:
- `identify joint LOG` on this machine: wall time and CPU time;
- the same with `--ray`, its driver replaced by one that runs each unit
  in its own process one after the other (`IdentifyProblem.fit`, no Ray):
  each unit's CPU and wall time, and that the plant file and report are
  the same (the units are pure);
- the same with `--ray` on local clusters of 1 and 2 raylets of one CPU
  each (results asserted equal to the local run), and `ray.put` of the
  log's text (what each identification ships once).

Simulated: a plane's units go to the first free of W workers (list
scheduling in start order), each costing its measured CPU time plus the
per-task overhead; the planes take turns (the program sends one plane's
starts at a time), and, for comparison, both planes' units at once.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import ray

from softjoint import ray_sweep

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ray_bench import makespan  # noqa: E402 - the same list scheduling

REPO = Path(__file__).resolve().parents[2]

# The driver that times each unit: `identify-serve`'s arguments, the
# units run here one after the other, one line of timing each to
# $UNIT_TIMES.
TIMING_SERVE = r'''
import json, os, sys, time
from softjoint import IdentifyProblem
args = sys.argv[sys.argv.index("identify-serve") + 1:]
del args[args.index("--address"):args.index("--address") + 2]
log = args[0]
prior = args[args.index("--prior") + 1] if "--prior" in args else None
problem = IdentifyProblem(open(log).read(), log,
                          None if prior is None else open(prior).read(), prior or "prior")
times = open(os.environ["UNIT_TIMES"], "a")
for line in sys.stdin:
    request = json.loads(line)
    answers = []
    for unit in request["units"]:
        c, w = time.process_time(), time.perf_counter()
        answers.append(json.loads(problem.fit(json.dumps(unit))))
        times.write(json.dumps({"plane": unit["plane"], "start": unit["start"],
                                "cpu_s": time.process_time() - c,
                                "wall_s": time.perf_counter() - w}) + "\n")
        times.flush()
    print(json.dumps({"id": request["id"], "answers": answers}), flush=True)
'''


def run(binary, args, env=None):
    """Wall and CPU seconds of the program (children's CPU), its output."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    p = subprocess.run([binary, *map(str, args)], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        sys.exit(f"softjoint {' '.join(map(str, args))} exited {p.returncode}: {p.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, p.stdout


def identified(stdout, plant):
    report = json.loads(stdout)
    report.pop("plant_file")
    return report, [l for l in Path(plant).read_text().splitlines() if not l.startswith("#")]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration-s", type=float, default=600)
    p.add_argument("--max-iterations", type=int, default=100)
    p.add_argument("--json", help="write the figures here")
    a = p.parse_args()
    binary = os.environ.get("SOFTJOINT_BIN") or str(REPO / "target/ci-opt/softjoint")
    d = Path(tempfile.mkdtemp(prefix="identify-ray-bench-"))
    plan = run(binary, ["identify", "plan", "--joint", "3d", "--duration-s", a.duration_s])[2]
    (d / "plan.toml").write_text(plan)
    run(binary, ["sim", "--excite", d / "plan.toml", "--log", d / "log.csv"])
    ident = lambda out: ["identify", "joint", d / "log.csv", "-o", out, "--json",
                         "--max-iterations", a.max_iterations, "--allow-unverified"]
    out = {"duration_s": a.duration_s, "max_iterations": a.max_iterations}
    wall, cpu, stdout = run(binary, ident(d / "local.toml"))
    want = identified(stdout, d / "local.toml")
    out["local_wall_s"], out["local_cpu_s"] = wall, cpu
    # Each unit timed, one after the other, without Ray.
    (d / "serve.py").write_text(TIMING_SERVE)
    wrapper = d / "python"
    wrapper.write_text(f"#!/bin/sh\nexec {sys.executable} {d / 'serve.py'} \"$@\"\n")
    wrapper.chmod(0o755)
    env = dict(os.environ, SOFTJOINT_PYTHON=str(wrapper), UNIT_TIMES=str(d / "units.jsonl"))
    wall, cpu, stdout = run(binary, ident(d / "timed.toml") + ["--ray", "none"], env)
    assert identified(stdout, d / "timed.toml") == want, "units run elsewhere must give the local result"
    units = [json.loads(l) for l in (d / "units.jsonl").read_text().splitlines()]
    out["units"] = units
    out["units_serial_wall_s"] = wall
    env = dict(os.environ, SOFTJOINT_PYTHON=sys.executable)
    log_text = (d / "log.csv").read_text()
    for raylets in (1, 2):
        with ray_sweep.LocalCluster(raylets=raylets, cpus=1) as c:
            t = time.perf_counter()
            ray.put(log_text)
            out[f"ray{raylets}_put_log_s"] = time.perf_counter() - t
            wall, cpu, stdout = run(binary, ident(d / f"ray{raylets}.toml") + ["--ray", c.address], env)
            assert identified(stdout, d / f"ray{raylets}.toml") == want, "Ray must give the local result"
            out[f"ray{raylets}_wall_s"] = wall
    out["log_bytes"] = len(log_text)
    for k, v in out.items():
        if k != "units":
            print(f"{k:24} {v:12.3f}" if isinstance(v, float) else f"{k:24} {v:>12}")
    cpu_by_plane = {}
    for u in units:
        cpu_by_plane.setdefault(u["plane"], []).append(u["cpu_s"])
    for plane, c in sorted(cpu_by_plane.items()):
        print(f"plane {plane}: {len(c)} units, CPU s " + ", ".join(f"{x:.1f}" for x in c))
    overhead = 0.006  # the crowded per-task figure of ray_bench.py
    serial = sum(u["cpu_s"] for u in units)
    print("\nmechanics units on W workers (1 CPU each): wall s, turns / both planes at once")
    rows = []
    for w in (1, 2, 4, 5, 8, 16, 64):
        turns = sum(makespan([x + overhead for x in c], w) for c in cpu_by_plane.values())
        both = makespan([x + overhead for c in cpu_by_plane.values() for x in c], w)
        rows.append((w, turns, both))
        print(f"W = {w:3}: {turns:8.1f} / {both:8.1f}   (serial {serial:.1f} CPU s)")
    out["simulated"] = rows
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
