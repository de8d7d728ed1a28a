"""The joint from Python, as one would in a notebook: simulate the default
scenario, plot its trace with matplotlib, then a small `tune` on Ray and
the same tune in this process.

    pip install target/wheels/softjoint-*.whl matplotlib ray
    python python/examples/joint_from_python.py [--out joint-trace.png] [--address ADDRESS]

Without --address the tune runs on a local cluster of two `ray start`
raylets that the script starts and stops (softjoint.ray_sweep.LocalCluster).
"""
import argparse
import sys
import time
from pathlib import Path

import softjoint

REPO = Path(__file__).resolve().parents[2]


def plot(trace, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    angles = [c[: -len("_true_deg")] for c in trace.columns if c.endswith("_true_deg")]
    fig, axes = plt.subplots(len(angles) + 1, 1, sharex=True, figsize=(8, 2.4 * (len(angles) + 1)))
    t = trace["t_s"]
    for ax, a in zip(axes, angles):
        ax.plot(t, trace[f"{a}_desired_deg"], "k--", lw=1, label="desired")
        ax.plot(t, trace[f"{a}_true_deg"], lw=1.2, label="true")
        ax.plot(t, trace[f"{a}_estimate_deg"], lw=0.8, label="estimate (wires)")
        ax.set_ylabel(f"{a} (°)")
        ax.legend(loc="lower right", fontsize=8)
    for c in [c for c in trace.columns if c.startswith("v")]:
        axes[-1].plot(t, trace[c], lw=0.8, label=c)
    axes[-1].set_ylabel("coil input (V)")
    axes[-1].set_xlabel("t (s)")
    axes[-1].legend(loc="upper right", fontsize=8, ncol=4)
    fig.suptitle(trace.summary["scenario"])
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--out", default="joint-trace.png")
    p.add_argument("--address", help="a Ray cluster to join (default: start two local raylets)")
    a = p.parse_args()

    trace = softjoint.simulate()  # the built-in default scenario, as `softjoint sim`
    print(f"{len(trace)} rows; steady-state error per angle (°):",
          trace.summary["steady_state_error_deg"])
    plot(trace, a.out)
    print(f"trace plotted to {a.out}")

    from softjoint import ray_sweep

    plant = softjoint.load_plant(REPO / "scenarios/identify/plant.toml")
    t = time.perf_counter()
    here = softjoint.tune(plant, 6, 2, seed=3)
    t_here = time.perf_counter() - t
    if a.address:
        ray_sweep.connect(a.address)
        t = time.perf_counter()
        on_ray = ray_sweep.tune(plant, 6, 2, seed=3)
    else:
        with ray_sweep.LocalCluster(raylets=2, cpus=1):
            t = time.perf_counter()
            on_ray = ray_sweep.tune(plant, 6, 2, seed=3)
    t_ray = time.perf_counter() - t
    g = on_ray["gains"]
    print(f"tune 6 candidates x 2 plants: here {t_here:.1f} s, on Ray {t_ray:.1f} s; "
          f"same result: {on_ray == here}")
    print(f"  K_P {g['controller']['kp_v_per_deg']}, robust cost "
          f"{g['tuning']['score']['robust']:.3f} (paper {g['tuning']['paper']['robust']:.3f})")
    return 0 if on_ray == here else 1


if __name__ == "__main__":
    sys.exit(main())
