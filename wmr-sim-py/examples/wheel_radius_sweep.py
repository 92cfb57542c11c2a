"""Worked example of book/src/how-to/python.md: how much does a wrong wheel radius in
the controller's model cost each controller?

The plant's wheels are made larger or smaller than the robot file says (the
controller keeps the file's radius), on `hil-sim sweep`'s base scenario (the
2 m circle, a disturbance in 10-35 s, motion capture through the firmware
runtime). All runs go in one batch across the cores; the window RMS
position error is plotted against the mismatch with matplotlib.

    python wheel_radius_sweep.py [--robot robots/paper.toml] [--duration 40]
                                 [--seeds 2] [--out wheel_radius_sweep.png]
"""

import argparse

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt
import numpy as np

import wmrsim

CONTROLLERS = ["smc", "asmc", "proposed"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", help="robot file [default: the paper's robot]")
    ap.add_argument("--duration", type=float, default=40.0, help="run length [s]")
    ap.add_argument("--seeds", type=int, default=2, help="seeds per point (noise)")
    ap.add_argument("--out", default="wheel_radius_sweep.png", help="figure file")
    a = ap.parse_args()

    robot = wmrsim.Robot.from_file(a.robot) if a.robot else wmrsim.Robot.paper()
    radius = robot.to_dict()["body"]["wheel_radius_m"]  # [right, left]
    mismatch = np.linspace(-0.05, 0.05, 11)  # plant radius / model radius - 1

    jobs, keys = [], []
    for seed in range(1, a.seeds + 1):
        base = wmrsim.Scenario.sweep_base(robot, seed=seed, duration_s=a.duration)
        for x in mismatch:
            plant_radius = [r * (1.0 + x) for r in radius]
            scn = base.replace({"plant": {"body": {"wheel_radius_m": plant_radius}}})
            for c in CONTROLLERS:
                jobs.append((scn, c))
                keys.append((seed, x, c))
    results = wmrsim.run_batch([s for s, _ in jobs], [c for _, c in jobs])

    rms = {c: np.zeros((a.seeds, len(mismatch))) for c in CONTROLLERS}
    for (seed, x, c), r in zip(keys, results):
        rms[c][seed - 1, list(mismatch).index(x)] = r.metrics["rms_pos_err_window_m"]

    print(f"window RMS position error [mm], robot {robot.name}, mean of {a.seeds} seeds")
    print("radius mismatch " + "".join(f"{c:>10}" for c in CONTROLLERS))
    for j, x in enumerate(mismatch):
        print(f"{100 * x:+14.0f} %" + "".join(f"{1e3 * rms[c][:, j].mean():10.2f}" for c in CONTROLLERS))

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for c in CONTROLLERS:
        ax.plot(100 * mismatch, 1e3 * rms[c].mean(axis=0), marker="o", label=c)
    ax.set_xlabel("plant wheel radius / model wheel radius - 1 [%]")
    ax.set_ylabel("window RMS position error [mm]")
    ax.set_title(f"Wheel-radius mismatch, robot {robot.name}, {a.duration:g} s runs")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(a.out, dpi=120)
    print(f"figure written to {a.out} ({len(results)} runs)")


if __name__ == "__main__":
    main()
