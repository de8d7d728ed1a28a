#!/usr/bin/env python3
"""How the paper's Ritz form of the fishbone belt (`method = "ritz"`)
depends on its discretisation and on the start (plant-models/src/dlo/
README.md, "The belt's highest point"). The default segment solver and its
independent reference are in scripts/belt_reference.py.

Solves the paper's Fig. 10 belt (scenarios/dlo/belt.toml) with
`softjoint dlo solve` for several Ritz bases, collocation counts and
initial bows, and prints one Markdown row per solve: energy, largest
constraint violation and the spine point farthest from the x = 0 plane
(mirrored to +x: the problem is symmetric under x -> -x, and a start can
settle on either side).

    cargo build --release -p host-tools
    python3 scripts/belt_study.py [path/to/softjoint]

About four minutes on one core. Deterministic: the solver has no random
draws.
"""
import csv
import json
import os
import subprocess
import sys
import tempfile

SOFTJOINT = sys.argv[1] if len(sys.argv) > 1 else "target/release/softjoint"
PAPER = (0.3, 0.4, -0.01)  # L1058, in L_u

# (harmonics, collocation points, integration intervals)
BASES = [(6, 16, 120), (6, 16, 240), (7, 16, 120), (7, 16, 240),
         (8, 24, 240), (10, 32, 240), (12, 40, 240)]
BOWS = [0.1, 0.2, 0.3, 0.5]

PROBLEM = """model = "belt"
[problem]
method = "ritz"
length_m = 1.0
width_m = 0.1
flexural_rigidity_n_m2 = 1.0
end_m = [0.0, 0.7, 0.0]
end_turn_rad = 0.5235987755982988
collocation_points = {points}
harmonics = {harmonics}
intervals = {intervals}
initial_bow_rad = {bow}
"""


def solve(work, harmonics, points, intervals, bow):
    name = f"h{harmonics}_p{points}_i{intervals}_b{bow}"
    toml = os.path.join(work, name + ".toml")
    out = os.path.join(work, name)
    with open(toml, "w") as f:
        f.write(PROBLEM.format(points=points, harmonics=harmonics,
                               intervals=intervals, bow=bow))
    run = subprocess.run([SOFTJOINT, "dlo", "solve", toml, "--out", out, "--json"],
                         capture_output=True, text=True)
    if run.returncode != 0:
        return None, run.stderr.strip().splitlines()[-1:]
    summary = json.loads(run.stdout)
    with open(os.path.join(out, "shape.csv")) as f:
        rows = list(csv.DictReader(f))
    top = max(rows, key=lambda r: abs(float(r["spine_x_m"])))
    point = (abs(float(top["spine_x_m"])), float(top["spine_y_m"]), float(top["spine_z_m"]))
    return (summary, point, float(top["spine_x_m"]) < 0), None


def main():
    print("| harmonics | points | intervals | bow (rad) | converged | energy (R_f/L_u) "
          "| max violation | highest spine point (L_u) | within ±0.02 of the paper |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for harmonics, points, intervals in BASES:
            for bow in BOWS:
                result, err = solve(work, harmonics, points, intervals, bow)
                if result is None:
                    print(f"| {harmonics} | {points} | {intervals} | {bow} | error: {err} | | | | |")
                    continue
                summary, p, mirrored = result
                inside = all(abs(a - b) <= 0.02 for a, b in zip(p, PAPER))
                side = " (mirrored)" if mirrored else ""
                print(f"| {harmonics} | {points} | {intervals} | {bow} | {summary['converged']} "
                      f"| {summary['energy_j']:.3f} | {summary['max_violation']:.1e} "
                      f"| [{p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}]{side} | {'yes' if inside else 'no'} |",
                      flush=True)


if __name__ == "__main__":
    main()
