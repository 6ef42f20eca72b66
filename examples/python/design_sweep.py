#!/usr/bin/env python3
"""Choose a module: how the uncertainty of the length scale moves with the design.

    python3 examples/python/design_sweep.py [--design examples/prototype_design.json]
        [--iterations 300] [--out design_sweep.png]

For each of spot noise, full angle, beams per side and source separation, a
JCGM 101 Monte Carlo of a measurement (opl.run_design_sweep) at several values,
plotted with matplotlib: the Monte Carlo standard deviation of L_photo with its
first-order prediction and the Cramer-Rao bound (relative, u(L) / L, for the
separation).
Expect (docs/method): linear in noise, falling with full angle and beam count,
relative uncertainty falling with separation. docs/python.md.
"""
import argparse
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import opl  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]

SWEEPS = [
    (opl.SweepParameter.NOISE_MM, [0.025, 0.05, 0.1, 0.2, 0.4], "spot noise [mm]"),
    (opl.SweepParameter.FULL_ANGLE_DEG, [10, 15, 20, 29, 40, 50], "full angle [deg]"),
    (opl.SweepParameter.BEAMS_PER_SIDE, [3, 5, 7, 11, 15, 21], "beams per side"),
    (opl.SweepParameter.SEPARATION_MM, [25, 40, 55, 80, 120, 200], "separation [mm]"),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--design", default=str(ROOT / "examples" / "prototype_design.json"))
    parser.add_argument("--iterations", type=int, default=300)
    parser.add_argument("--out", default="design_sweep.png")
    args = parser.parse_args()

    try:
        design = opl.ModuleDesign.read(args.design)
    except opl.Error as e:
        print(f"design_sweep.py: {e}", file=sys.stderr)
        return 1
    options = opl.MonteCarloOptions()
    options.iterations = args.iterations

    fig, axes = plt.subplots(2, 2, figsize=(11, 8), constrained_layout=True)
    for ax, (parameter, values, label) in zip(axes.flat, SWEEPS):
        sweep = opl.run_design_sweep(design, parameter, values, options)
        x = np.array([p.value for p in sweep.points])
        photo = [p.report.lengths[0].photo_mm for p in sweep.points]
        mc = np.array([s.std_dev for s in photo]) * 1e3
        first = np.array([s.first_order_std for s in photo]) * 1e3
        bound = np.array([s.cramer_rao_std for s in photo]) * 1e3
        true_mm = np.array([p.report.lengths[0].true_mm for p in sweep.points])
        if parameter == opl.SweepParameter.SEPARATION_MM:
            # u(L) hardly moves with the baseline: what falls is u(L) / L.
            scale, unit = 1e3 / true_mm, "u(L) / L [ppm]"
        else:
            scale, unit = 1.0, "u(L) [um]"
        ax.plot(x, mc * scale, "o-", label="Monte Carlo std")
        ax.plot(x, first * scale, "s--", label="first order")
        if bound.any():
            ax.plot(x, bound * scale, ":", color="black", label="Cramer-Rao bound")
        ax.set_xlabel(label)
        ax.set_ylabel(unit)
        ax.set_ylim(bottom=0)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        for v, u, r in zip(x, mc, mc / 1e3 / true_mm * 1e6):
            print(f"{sweep.parameter.name:15s} {v:8.3f}  u(L) {u:8.2f} um  {r:8.0f} ppm")
    name = pathlib.Path(args.design).name
    fig.suptitle(f"Uncertainty of the length scale, {name}, {args.iterations} Monte Carlo iterations per point")
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
