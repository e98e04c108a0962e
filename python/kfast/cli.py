"""``python -m kfast``: the command line.

    python -m kfast demo [--steps T] [--seed S] [--plot out.png]
    python -m kfast bench [--quick]
    python -m kfast info

``demo`` simulates a target moving in the plane with a 2-D constant-velocity model (white-noise
acceleration), measures its position in noise, filters and smooths it, and prints how much the
filter improves on the raw measurements; ``--plot`` writes the track with covariance ellipses
and the estimates with their bands (matplotlib, the ``plot`` extra). ``bench`` times a few of
the benchmark workloads against whichever peers are installed and prints the ratio table.
``info`` prints the version, the build and the CPU features the loops use.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any, Optional

import numpy as np

import kfast


def constant_velocity_2d(dt: float = 0.1, q: float = 1.0, r: float = 1.0) -> kfast.LinearGaussian:
    """The demo's (and the benchmarks' "CV") model: kfast.models.constant_velocity in 2-D."""
    return kfast.models.constant_velocity(2, dt, q=q, r=r)


def demo(steps: int, seed: int, plot: Optional[str] = None) -> None:
    model = constant_velocity_2d()
    x0 = np.array([1.0, -1.0, 0.5, 0.2])
    P0 = np.diag([10.0, 10.0, 1.0, 1.0])
    truth, y = model.simulate(steps, x0, P0, seed=seed)
    res = model.filter(y, x0, P0, outputs=("x_filt",))
    x_filt = res.x_filt
    assert x_filt is not None

    def rmse(err):
        return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))

    print(f"kfast {kfast.__version__} demo: 2-D constant-velocity target, {steps} steps, dt = 0.1, seed {seed}")
    print(f"  position RMSE of the raw measurements : {rmse(y - truth[:, :2]):.4f}")
    print(f"  position RMSE of the filtered estimate: {rmse(x_filt[:, :2] - truth[:, :2]):.4f}")
    print(f"  velocity RMSE of the filtered estimate: {rmse(x_filt[:, 2:] - truth[:, 2:]):.4f}")
    print(f"  log-likelihood of the measurements    : {res.loglik:.4f}")
    if plot is not None:
        write_demo_plot(plot, model, truth, y, x0, P0)
        print(f"  plot written to {plot}")


def write_demo_plot(path: str, model: kfast.LinearGaussian, truth: np.ndarray, y: np.ndarray, x0: np.ndarray,
                    P0: np.ndarray) -> Any:
    """The demo's figure: the first 100 steps of the 2-D track (smoothed, with 95% ellipses;
    truth; measurements) and the smoothed velocity components with their bands over all steps.
    Returns the figure."""
    try:
        import matplotlib
    except ImportError as exc:
        raise SystemExit('--plot needs matplotlib: pip install "kfast[plot]"') from exc

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    smoothed = model.smooth(y, x0, P0)
    fig = plt.figure(figsize=(11, 5.5), layout="constrained")
    panels: Any = fig.subfigures(1, 2, width_ratios=[1.1, 1])
    left, right = panels
    shown = min(len(y), 100)
    track = kfast.plot.plot_track(smoothed, truth=truth, y=y, every=5, window=(0, shown), ax=left.subplots())
    track.set_title(f"position, steps 0-{shown - 1}", fontsize="medium")
    kfast.plot.plot_estimates(smoothed, components=[2, 3], truth=truth, names=["velocity x", "velocity y"],
                              ax=right.subplots(2, 1, sharex=True))
    fig.suptitle(f"kfast {kfast.__version__}: RTS smoother of a 2-D constant-velocity target")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return fig


def info() -> None:
    import platform

    details = kfast.kernel_info()
    print(f"kfast {kfast.__version__} ({details['build']} build, {details['target']})")
    print(f"  Python {platform.python_version()}, NumPy {np.__version__}")
    print(f"  extension: {kfast._kfast.__file__}")
    print(f"  instruction set: {details['instruction_set']} (deterministic mode {'on' if details['deterministic'] else 'off'})")
    print(f"  CPU features detected: {details['cpu_features']}")
    print(f"  compiled sizes: {details['fixed_sizes']}")
    print(f"  threads (batch functions, threads=None): {details['threads']}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m kfast", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p_demo = sub.add_parser("demo", help="filter a simulated 2-D constant-velocity target")
    p_demo.add_argument("--steps", type=int, default=1000)
    p_demo.add_argument("--seed", type=int, default=0)
    p_demo.add_argument("--plot", metavar="PATH", help="write a figure of the result (PNG, SVG or PDF by the suffix)")
    p_bench = sub.add_parser("bench", help="time workloads W1, W3, W7 against the installed peers")
    p_bench.add_argument("--quick", action="store_true", help="short series and few rounds (seconds, noisy)")
    sub.add_parser("info", help="version, build, CPU features and threads")
    args = parser.parse_args(argv)
    if args.command == "demo":
        if args.steps < 1:
            parser.error("--steps: expected a positive number of steps")
        demo(args.steps, args.seed, args.plot)
    elif args.command == "bench":
        from kfast import _bench

        _bench.run(quick=args.quick)
    else:
        info()
    return 0


if __name__ == "__main__":
    sys.exit(main())
