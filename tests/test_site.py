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
    for page in ("index.html", "getting-started/index.html", "guide/linear/index.html", "guide/steady-state/index.html",
                 "guide/estimation/index.html", "guide/nonlinear/index.html", "guide/control/index.html",
                 "migration/index.html", "conventions/index.html", "guide/continuous/index.html",
                 "guide/particles/index.html", "benchmarks/index.html", "reference/index.html",
                 *(f"reference/{p}/index.html" for p in ("linear", "riccati", "nonlinear", "control", "tools"))):
        assert (site / page).is_file(), page


def test_guides_show_their_checks(site):
    def text(page):
        return (site / "guide" / page / "index.html").read_text()

    assert "the same from the DARE: True" in text("steady-state")
    assert "K_pred = F K (N = 0): True" in (site / "conventions" / "index.html").read_text()
    continuous = text("continuous")
    assert "Qd = [[0.041667, 0.125], [0.125, 0.5]]" in continuous  # h^3/3, h^2/2, h at h = 0.5
    assert "Kalman-Bucy P and K: [0.414214] [0.414214]" in continuous  # sqrt(2) - 1
    particles = text("particles")
    assert "ParticleResult(T=100" in particles and "IMMResult(T=200, r=2" in particles and "<svg" in particles
    assert "error variance 10.76" in text("control")  # Söderström Example 7.1
    nonlinear = text("nonlinear")
    assert all(f"{name}" in nonlinear for name in ("UKF ", "EKF ", "particle filter ")) and "position RMSE 0." in nonlinear
    assert "after" in text("estimation") and "EM:" in text("estimation")


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
    html = "".join((site / "reference" / page / "index.html").read_text()
                   for page in ("linear", "riccati", "nonlinear", "control", "tools"))
    for name in ("LinearGaussian", "smooth_fixed_lag", "filter_batch", "KalmanFilter", "plot_track",
                 "solve_discrete_are", "ParticleFilter", "lqg", "set_deterministic"):
        assert name in html, name


def test_migration_guide_shows_the_peers_agree(site):
    """Every difference the migration page printed (filterpy, pykalman, statsmodels against
    kfast on the same data) is at rounding level."""
    import re

    html = (site / "migration" / "index.html").read_text()
    found = re.findall(r"(x_filt|P_filt|loglik|x_smooth|K_pred|vs batch): ([0-9.e+-]+)", html)
    names = [name for name, _ in found]
    assert names.count("x_filt") == 3 and "K_pred" in names and "x_smooth" in names, found
    assert all(float(value) < 1e-9 for _, value in found), found


def chromium():
    import shutil

    return shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")


@pytest.mark.skipif(chromium() is None, reason="no headless Chromium (.ci/run installs Debian's chromium)")
def test_pages_render_in_a_headless_browser(site, tmp_path):
    """Each page opened in headless Chromium: the DOM after its scripts ran has the page's
    title and content (no traceback in the examples' output), the getting-started page draws its plot, and a
    screenshot is a real image."""
    import struct

    pages = {
        "getting-started/index.html": ("Getting started", "position RMSE"),
        "guide/linear/index.html": ("Linear filtering and smoothing", "P_filt"),
        "guide/nonlinear/index.html": ("Nonlinear filters", "particle filter"),
        "migration/index.html": ("Coming from filterpy", "statsmodels"),
        "reference/linear/index.html": ("Linear models", "smooth_fixed_lag"),
    }
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--window-size=1200,1800"]
    for page, (title, text) in pages.items():
        url = (site / page).as_uri()
        dom = subprocess.run([chromium(), *flags, "--virtual-time-budget=1000", "--dump-dom", url],
                             capture_output=True, text=True, timeout=120).stdout
        assert f"<title>{title}" in dom and text in dom, page
        if not page.startswith("reference"):  # (the API docstrings show expected errors)
            assert "Traceback" not in dom, page
    dom = subprocess.run([chromium(), *flags, "--dump-dom", (site / "getting-started/index.html").as_uri()],
                         capture_output=True, text=True, timeout=120).stdout
    # The track figure: matplotlib's SVG with its ellipse patches and lines, inline in the page.
    figure = dom[dom.index("<svg", dom.index("Plot the result")):]
    assert figure.count("patch_") >= 20 and "line2d_" in figure
    shot = tmp_path / "shot.png"
    subprocess.run([chromium(), *flags, f"--screenshot={shot}", (site / "getting-started/index.html").as_uri()],
                   capture_output=True, timeout=120)
    head = shot.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and struct.unpack(">II", head[16:24]) == (1200, 1800)


def test_the_benchmarks_page_shows_the_latest_results(site):
    # The page reads BENCHMARKS.md when the site is built: its headline W1 figure is the
    # results table's, not a copy.
    results = (ROOT / "BENCHMARKS.md").read_text().split("\n## Results", 1)[1]
    row = next(line for line in results.splitlines() if line.startswith("| kfast standard, x_filt+P_filt |"))
    w1 = row.split("|")[3].strip()
    run = next(line for line in results.splitlines() if line.startswith("Run: "))[5:].strip()
    html = (site / "benchmarks" / "index.html").read_text()
    assert f"<td style=\"text-align: right;\">{w1}</td>" in html or f">{w1}<" in html
    assert f"Run of {run}" in html
