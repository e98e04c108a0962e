"""The documentation site (mkdocs.yml, pages in site/) builds with warnings as errors, its
examples run at build time (markdown-exec: a failing example is a warning, so a failed build),
and the built pages have the example outputs, the plot and the API reference."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
pytest.importorskip("mkdocs")  # in the test extras: never skipped in CI


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)], cwd=ROOT,
                         capture_output=True, text=True, env=env)
    assert run.returncode == 0, run.stdout + run.stderr
    return out


def test_pages_are_built(site):
    for page in ("index.html", "getting-started/index.html", "guide/linear/index.html", "reference/api/index.html"):
        assert (site / page).is_file(), page


def test_examples_ran_and_the_plot_is_there(site):
    html = (site / "getting-started" / "index.html").read_text()
    assert "position RMSE, smoothed" in html and "FilterResult(" in html
    assert html.count("<svg") >= 2  # the track figure (besides the theme's icons)
    assert "Ellipse" not in html  # drawn, not printed
    # The guide's missing-data example printed what the filter computes now.
    import numpy as np

    import kfast

    model = kfast.LinearGaussian(F=[[0.9]], H=[[1.0]], Q=[[0.19]], R=[[1.0]])
    res = model.filter(np.array([0.3, np.nan, 0.7, 1.2, np.nan, -0.4]), x0=0.0, P0=1.0)
    guide = (site / "guide" / "linear" / "index.html").read_text()
    assert str(np.round(res.x_filt[:, 0], 4)) in guide and str(np.round(res.P_filt[:, 0, 0], 4)) in guide


def test_api_reference_comes_from_the_docstrings(site):
    html = (site / "reference" / "api" / "index.html").read_text()
    for name in ("LinearGaussian", "smooth_fixed_lag", "filter_batch", "KalmanFilter", "plot_track"):
        assert name in html, name
