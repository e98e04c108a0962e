"""The peer of bench_particle.py that needs numpy < 2: Chopin's `particles`, in its own venv.
Run by bench_particle.py as

    <particles venv>/bin/python benches/peers_particle.py DIR

DIR holds y.npy and job.json ({"rounds": r, "particles": N}). Writes DIR/timings.json: the
seconds per call (one per round, after a warm-up call), the filtered means and variances and the
log-likelihood of the last call, and the version. The model is bench_particle.py's UNGM, written
in particles' terms (PX(t, xp) is the law of x[t] given x[t-1], so its cosine is at t - 1).

Creating the venv: python3 -m venv /work/venv-particles && /work/venv-particles/bin/pip install
"numpy<2" particles
"""

from __future__ import annotations

import json
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402


def main(directory):
    import particles
    from particles import distributions as dists
    from particles import state_space_models as ssm
    from particles.collectors import Moments

    class UNGM(ssm.StateSpaceModel):
        default_params = {"q": 10.0, "r": 1.0}

        def PX0(self):
            return dists.Normal(loc=0.0, scale=np.sqrt(5.0))

        def PX(self, t, xp):
            return dists.Normal(loc=xp / 2 + 25 * xp / (1 + xp**2) + 8 * np.cos(1.2 * (t - 1)), scale=np.sqrt(self.q))

        def PY(self, t, xp, x):
            return dists.Normal(loc=x**2 / 20, scale=np.sqrt(self.r))

    with open(os.path.join(directory, "job.json")) as f:
        job = json.load(f)
    y = np.load(os.path.join(directory, "y.npy"))

    def run(seed):
        np.random.seed(seed)
        fk = ssm.Bootstrap(ssm=UNGM(), data=list(y))
        # ESSrmin = 1: resample whenever ESS < N, i.e. at every step (systematic)
        pf = particles.SMC(fk=fk, N=job["particles"], resampling="systematic", ESSrmin=1.0, collect=[Moments()])
        pf.run()
        return pf

    run(0)
    samples = []
    for r in range(job["rounds"]):
        t = time.perf_counter()
        pf = run(r + 1)
        samples.append(time.perf_counter() - t)
    moments = pf.summaries.moments
    out = {
        "samples": samples,
        "mean": [float(m["mean"]) for m in moments],
        "var": [float(m["var"]) for m in moments],
        "loglik": float(pf.summaries.logLts[-1]),
        "version": getattr(particles, "__version__", "?"),
    }
    with open(os.path.join(directory, "timings.json"), "w") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main(sys.argv[1])
