"""Configuration of the fuzz campaign (docs/reliability.md).

Two profiles, both derandomized (the same cases on every run):

* fast (default): runs in CI as part of ``python -m pytest tests``;
* long: ``python -m pytest tests/fuzz --long`` (the option is known when tests/fuzz is on the
  command line), or ``KFAST_FUZZ_PROFILE=long python -m pytest tests``. ``KFAST_FUZZ_SEED=<int>``
  explores other cases (Hypothesis' seed), still reproducibly.

The cases run in one isolated worker process (isolation.py), shared by the session.
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, Phase, settings

from isolation import Worker

# Examples per (entry point, family) test and the per-case timeout of each profile.
PROFILES = {"fast": dict(max_examples=14, timeout=5.0), "long": dict(max_examples=400, timeout=30.0)}

for _name, _p in PROFILES.items():
    settings.register_profile(
        f"kfast-fuzz-{_name}",
        max_examples=_p["max_examples"],
        derandomize=os.environ.get("KFAST_FUZZ_SEED") is None,
        database=None,
        deadline=None,
        # no shrinking: every case is already one perturbation of a tiny valid problem, and a
        # hang would be re-run many times
        phases=[Phase.explicit, Phase.generate],
        suppress_health_check=list(HealthCheck),
    )


def pytest_addoption(parser):
    parser.addoption("--long", action="store_true", default=False, help="run the long fuzz profile (docs/reliability.md)")


@pytest.fixture(scope="session")
def fuzz_profile(request) -> str:
    try:
        long = request.config.getoption("--long")
    except ValueError:  # tests/fuzz was not on the command line: the option is not registered
        long = False
    return "long" if long or os.environ.get("KFAST_FUZZ_PROFILE") == "long" else "fast"


@pytest.fixture(scope="session")
def fuzz_settings(fuzz_profile) -> settings:
    return settings.get_profile(f"kfast-fuzz-{fuzz_profile}")


@pytest.fixture(scope="session")
def worker(fuzz_profile):
    w = Worker(timeout=PROFILES[fuzz_profile]["timeout"])
    yield w
    w.close()
