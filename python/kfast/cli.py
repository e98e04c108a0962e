"""``python -m kfast``: the command line.

    python -m kfast demo [--steps T] [--seed S]

The demo simulates a target moving in the plane with a 2-D constant-velocity model (white-noise
acceleration), measures its position in noise, filters it, and prints how much the filter
improves on the raw measurements.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import kfast


def constant_velocity_2d(dt: float = 0.1, q: float = 1.0, r: float = 1.0) -> kfast.LinearGaussian:
    """The demo's (and the benchmarks' "CV") model: kfast.models.constant_velocity in 2-D."""
    return kfast.models.constant_velocity(2, dt, q=q, r=r)


def demo(steps: int, seed: int) -> None:
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m kfast", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p_demo = sub.add_parser("demo", help="filter a simulated 2-D constant-velocity target")
    p_demo.add_argument("--steps", type=int, default=1000)
    p_demo.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.command == "demo":
        demo(args.steps, args.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
