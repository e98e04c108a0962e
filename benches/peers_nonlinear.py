"""The peers of bench_nonlinear.py that live in their own venv: dynamax's UKF and EKF (JAX) and
Stone Soup's UKF. Run by bench_nonlinear.py as

    <peer venv>/bin/python benches/peers_nonlinear.py DIR

DIR holds the inputs as .npy files (y, Q, R, x0, P0) and job.json ({"rounds": r, "runs": {name:
steps}}). For each run this writes DIR/<name>.x_filt.npy, and into DIR/timings.json its
seconds per call (one per round, after a warm-up call that also compiles) or its error, and the
peers' versions. Every run computes filtered means and covariances, as kfast does. The model
(CT, dt = 0.1, range-bearing radar at the origin) is that of bench_nonlinear.py, written again
here in each peer's own terms.
"""

from __future__ import annotations

import json
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("JAX_PLATFORMS", "cpu")

import numpy as np  # noqa: E402

DT = 0.1
ALPHA, BETA, KAPPA = 0.5, 2.0, 0.0


def ct(xp, px, py, vx, vy, w):
    """The CT transition for arrays of points, in numpy or jax.numpy (xp)."""
    S, C = xp.sin(w * DT), xp.cos(w * DT)
    small = xp.abs(w) < 1e-9
    ws = xp.where(small, 1.0, w)  # no 0/0, so no NaN in jax's derivatives either
    s = xp.where(small, DT, S / ws)
    c = xp.where(small, 0.0, (1 - C) / ws)
    return [px + s * vx - c * vy, py + c * vx + s * vy, C * vx - S * vy, S * vx + C * vy, w]


def dynamax_runs(data, names):
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    from dynamax.nonlinear_gaussian_ssm import (
        ParamsNLGSSM, UKFHyperParams, extended_kalman_filter, unscented_kalman_filter,
    )

    # dynamax conditions on emissions[0] first: initial_mean/covariance is x(0|-1), P(0|-1).
    # Its psd_solve adds 1e-9 I to S before the gain; against the bearing variance (7.6e-5) that
    # moves x_filt by 1e-5 to 1e-3 (patched to 0, the UKF matches kfast to ~1e-9).
    # dynamax has no angle wrapping, and the track's bearing crosses +-pi (first at step 2,285):
    # h gets the observed bearing as its input u and returns each bearing within pi of it, so
    # y - h(x) is the wrapped innovation that kfast uses.
    def h(x, u):
        b = jnp.arctan2(x[1], x[0])
        return jnp.stack([jnp.hypot(x[0], x[1]), b + 2 * jnp.pi * jnp.round((u[0] - b) / (2 * jnp.pi))])

    params = ParamsNLGSSM(
        jnp.asarray(data["x0"]), jnp.asarray(data["P0"]), lambda x, u: jnp.stack(ct(jnp, *x)),
        jnp.asarray(data["Q"]), h, jnp.asarray(data["R"]),
    )
    fields = ["filtered_means", "filtered_covariances"]
    filters = {
        "dynamax UKF": lambda e: unscented_kalman_filter(
            params, e, UKFHyperParams(alpha=ALPHA, beta=BETA, kappa=KAPPA), e[:, 1:], fields),
        # Jacobians by jacfwd of f and h: derivatives of the formulas, as kfast's built-in has
        "dynamax EKF": lambda e: extended_kalman_filter(params, e, e[:, 1:], output_fields=fields),
    }

    def timed(flt, steps):
        run = jax.jit(lambda e: (lambda r: (r.filtered_means, r.filtered_covariances))(flt(e)))
        e = jax.device_put(jnp.asarray(data["y"][:steps]))
        return lambda: np.asarray(jax.block_until_ready(run(e))[0])

    return {name: timed(filters[name], steps) for name, steps in names.items()}


def stonesoup_ukf(data, steps):
    from datetime import datetime, timedelta

    from stonesoup.base import Property
    from stonesoup.models.base import TimeInvariantModel
    from stonesoup.models.measurement.nonlinear import NonLinearGaussianMeasurement
    from stonesoup.models.transition.nonlinear import GaussianTransitionModel
    from stonesoup.predictor.kalman import UnscentedKalmanPredictor
    from stonesoup.types.array import CovarianceMatrix, StateVectors
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.prediction import GaussianStatePrediction
    from stonesoup.updater.kalman import UnscentedKalmanUpdater

    # Own models: Stone Soup's ConstantTurn orders the state (x, vx, y, vy, w) and has its own
    # Q; CartesianToBearingRange gives (bearing, range) as Bearing objects. These keep kfast's
    # order, Q and plain floats (no wrapping: the short series ends before the bearing first
    # crosses +-pi, at step 2,285).
    class CT(GaussianTransitionModel, TimeInvariantModel):
        Q: CovarianceMatrix = Property(doc="process noise covariance")

        @property
        def ndim_state(self):
            return 5

        def function(self, state, noise=False, **kwargs):
            return StateVectors(np.array(ct(np, *np.asarray(state.state_vector, dtype=float))))

        def covar(self, **kwargs):
            return self.Q

    class RangeBearing(NonLinearGaussianMeasurement):
        @property
        def ndim_meas(self):
            return 2

        def function(self, state, noise=False, **kwargs):
            X = np.asarray(state.state_vector, dtype=float)
            return StateVectors(np.array([np.hypot(X[0], X[1]), np.arctan2(X[1], X[0])]))

    radar = RangeBearing(ndim_state=5, mapping=(0, 1), noise_covar=CovarianceMatrix(data["R"]))
    # kappa given: Stone Soup's default is 3 - n, not 0
    predictor = UnscentedKalmanPredictor(CT(Q=CovarianceMatrix(data["Q"])), alpha=ALPHA, beta=BETA, kappa=KAPPA)
    updater = UnscentedKalmanUpdater(radar, alpha=ALPHA, beta=BETA, kappa=KAPPA)
    y = data["y"][:steps]
    t0 = datetime(2024, 6, 1)

    def run():
        x, P = np.zeros((len(y), 5)), np.zeros((len(y), 5, 5))
        prior = GaussianStatePrediction(data["x0"][:, None], data["P0"], timestamp=t0)
        for t in range(len(y)):
            when = t0 + timedelta(seconds=DT * t)
            if t:
                prior = predictor.predict(post, timestamp=when)
            post = updater.update(SingleHypothesis(prior, Detection(y[t][:, None], timestamp=when, measurement_model=radar)))
            x[t], P[t] = post.state_vector.ravel(), post.covar
        return x

    return run


def main(folder):
    data = {k: np.load(os.path.join(folder, k + ".npy")) for k in ("y", "Q", "R", "x0", "P0")}
    with open(os.path.join(folder, "job.json")) as f:
        job = json.load(f)
    timings = {}
    for name, steps in job["runs"].items():
        try:
            if name.startswith("dynamax"):
                fn = dynamax_runs(data, {name: steps})[name]
            else:
                fn = stonesoup_ukf(data, steps)
            x = fn()  # warm-up: jit compiles here
            samples = []
            for _ in range(job["rounds"]):
                t = time.perf_counter()
                fn()
                samples.append(time.perf_counter() - t)
            np.save(os.path.join(folder, name + ".x_filt.npy"), x)
            timings[name] = {"steps": steps, "samples": samples}
        except ImportError as e:
            timings[name] = {"steps": steps, "error": f"not installed ({e.name})"}
        except Exception as e:  # noqa: BLE001 -- reported in the bench's table
            timings[name] = {"steps": steps, "error": f"failed: {type(e).__name__}: {e}".splitlines()[0][:110]}
    versions = {}
    for module in ("jax", "dynamax", "stonesoup"):
        try:
            versions[module] = __import__(module).__version__
        except ImportError:
            versions[module] = "not installed"
    with open(os.path.join(folder, "timings.json"), "w") as f:
        json.dump({"runs": timings, "versions": versions}, f)


if __name__ == "__main__":
    main(sys.argv[1])
