#!/usr/bin/env python3
"""One step of the Table I rope (N = 50, hanging from its top point, no
contact) against MuJoCo's mass-spring flex of the same chain, side by side
(issue 34).

What is compared, exactly:

* the project: `rope_steps hanging K` (plant-models/dlo/examples), the
  rope of plant-dlo with its defaults (Table I: 50 points of 0.05 kg, 5 m,
  k_l = 800 N, linear, torsional and swivel springs and dampers, self-
  collision search every step with r = 0.05 m, semi-implicit Euler at
  dt = 1 ms). Its CPU time per step is (t(2K) − t(K)) / K, the child
  process's user + system time, so the set-up cancels.
* MuJoCo (from PyPI, `pip install mujoco`): a one-dimensional flex of the
  same 50 vertices (total mass 2.5 kg, rest spacing 5/49 m, radius
  0.05 m) whose edges are springs of k = k_l / l_r = 7,843 N/m with
  damping 1 N·s/m, vertex 0 pinned, self-collision left on ("auto"),
  Euler integrator at 1 ms. It has no bending or torsion, so it does less
  physics per step than the project's rope. CPU time per step of
  `mj_step(model, data, nstep=K)` (the loop runs in C).

Rounds alternate the two so that both see the same machine load; the
medians and their ratio are printed. Both ropes must hang (the lowest
point below its start) or the script exits 1; exit 2 for a bad argument.

Usage: scripts/rope_mujoco_compare.py [--exe PATH] [--steps K] [--rounds R]
(build the example first: cargo build --release -p plant-dlo --example
rope_steps).
"""
import argparse
import os
import resource
import statistics
import subprocess
import sys
import time

N, LENGTH_M, MASS_KG, K_L_N, RADIUS_M = 50, 5.0, 0.05, 800.0, 0.05
REST_M = LENGTH_M / (N - 1)

FLEX_XML = f"""
<mujoco>
  <option timestep="0.001" integrator="Euler" gravity="0 0 -9.8"/>
  <worldbody>
    <flexcomp name="rope" type="grid" dim="1" count="{N} 1 1"
              spacing="{REST_M!r} 1 1" pos="0 0 10" euler="0 90 0"
              radius="{RADIUS_M}" mass="{N * MASS_KG}">
      <edge stiffness="{K_L_N / REST_M!r}" damping="1.0"/>
      <contact selfcollide="auto"/>
      <pin id="0"/>
    </flexcomp>
  </worldbody>
</mujoco>
"""


def rope_seconds(exe, steps):
    """CPU seconds of `rope_steps hanging steps` and its last point's z."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([exe, "hanging", str(steps)], capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        sys.exit(f"rope_mujoco_compare: {exe} failed: {out.stderr.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, float(out.stdout.split()[-1])


def mujoco_seconds(mujoco, model, steps):
    """CPU seconds of `steps` MuJoCo steps from rest, and the lowest z."""
    data = mujoco.MjData(model)
    start = time.process_time()
    mujoco.mj_step(model, data, nstep=steps)
    cpu = time.process_time() - start
    return cpu, float(data.flexvert_xpos[:, 2].min())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--exe", default="target/release/examples/rope_steps")
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args()
    if a.steps < 1 or a.rounds < 1:
        ap.error("--steps and --rounds must be at least 1")
    if not os.access(a.exe, os.X_OK):
        ap.error(f"--exe {a.exe}: not an executable (build the rope_steps example)")
    import mujoco

    model = mujoco.MjModel.from_xml_string(FLEX_XML)
    if model.nflexvert != N or model.flex_selfcollide[0] == 0:
        sys.exit("rope_mujoco_compare: the flex is not the 50-vertex self-colliding chain")
    ours, theirs = [], []
    for _ in range(a.rounds):
        t1, _ = rope_seconds(a.exe, a.steps)
        t2, z_ours = rope_seconds(a.exe, 2 * a.steps)
        ours.append((t2 - t1) / a.steps)
        t, z_theirs = mujoco_seconds(mujoco, model, a.steps)
        theirs.append(t / a.steps)
    # Both ropes hang: the bottom point is below where it started (5 m
    # below the top for the project, 7.5 m for the flex centred at 10 m).
    if not (z_ours < 5.0 and z_theirs < 7.5):
        sys.exit(f"rope_mujoco_compare: a rope did not hang (z {z_ours}, {z_theirs})")
    o, t = statistics.median(ours), statistics.median(theirs)
    print(f"mujoco {mujoco.__version__}, {a.rounds} rounds of {a.steps} steps")
    print(f"project rope step: {o * 1e6:.2f} us (median; rounds {[round(x * 1e6, 2) for x in ours]})")
    print(f"MuJoCo flex step:  {t * 1e6:.2f} us (median; rounds {[round(x * 1e6, 2) for x in theirs]})")
    print(f"MuJoCo / project: {t / o:.2f}x")


if __name__ == "__main__":
    main()
