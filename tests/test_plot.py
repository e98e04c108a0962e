"""kfast.plot with matplotlib's Agg backend: each figure has the artists it should, and they
carry the numbers they should (bands at x ± z σ, ellipses from the covariance, weights as
areas); the demo writes a PNG; bad input gets clear errors."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.collections import PathCollection, PolyCollection  # noqa: E402
from matplotlib.patches import Ellipse  # noqa: E402

import kfast  # noqa: E402
from kfast.cli import write_demo_plot  # noqa: E402

Z95 = 1.959963984540054


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def cv_run(T=60, seed=2):
    model = kfast.models.constant_velocity(2, 0.1, q=1.0, r=0.5)
    x0, P0 = np.array([0.0, 0.0, 1.0, 0.5]), np.diag([4.0, 4.0, 1.0, 1.0])
    truth, y = model.simulate(T, x0, P0, seed=seed)
    return model, x0, P0, truth, y


def test_estimates_have_bands_truth_and_measurements():
    model, x0, P0, truth, y = cv_run()
    res = model.filter(y, x0, P0)
    axes = kfast.plot.plot_estimates(res, truth=truth, y=y, observed=[0, 1])
    assert len(axes) == 4
    for c, ax in enumerate(axes):
        bands = [a for a in ax.collections if isinstance(a, PolyCollection)]
        assert len(bands) == 1
        lines = {line.get_label(): line for line in ax.get_lines()}
        assert "filtered estimate" in lines and "truth" in lines
        assert ("measurements" in lines) == (c < 2)
        np.testing.assert_allclose(lines["filtered estimate"].get_ydata(), res.x_filt[:, c])
        # The band's upper edge at t = 10 is x + z sqrt(P_cc).
        verts = bands[0].get_paths()[0].vertices
        upper = verts[(np.isclose(verts[:, 0], 10.0)), 1].max()
        assert upper == pytest.approx(res.x_filt[10, c] + Z95 * np.sqrt(res.P_filt[10, c, c]), rel=1e-12)
    sm = model.smooth(y, x0, P0)
    axes = kfast.plot.plot_estimates(sm, components=[1], level=0.5)
    assert len(axes) == 1 and axes[0].get_lines()[0].get_label() == "smoothed estimate"


def test_track_ellipses_are_the_covariance_level_sets():
    model, x0, P0, truth, y = cv_run(T=50)
    res = model.filter(y, x0, P0)
    ax = kfast.plot.plot_track(res, truth=truth, y=y, every=10, level=0.9)
    ellipses = [p for p in ax.patches if isinstance(p, Ellipse)]
    assert len(ellipses) == 5
    radius2 = -2 * np.log(0.1)  # the chi-square(2) 90% quantile
    for k, e in enumerate(ellipses):
        C = res.P_filt[10 * k][:2, :2]
        assert e.center == pytest.approx(tuple(res.x_filt[10 * k, :2]))
        # Semi-axes are sqrt(quantile * eigenvalue).
        axes_sq = sorted([(e.width / 2) ** 2, (e.height / 2) ** 2])
        np.testing.assert_allclose(axes_sq, radius2 * np.linalg.eigvalsh(C), rtol=1e-10)
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["measurements", "truth", "filtered estimate"]


def test_innovations_mode_probabilities_and_particles():
    model, x0, P0, truth, y = cv_run(T=80)
    y[5] = np.nan
    axes = kfast.plot.plot_innovations(model.filter(y, x0, P0))
    assert len(axes) == 2 and len(axes[0].get_lines()) == 2 + 2  # two components, ±z
    nis = axes[1].get_lines()[0].get_ydata()
    assert np.isnan(nis[5]) and np.all(np.isfinite(np.delete(nis, 5)))

    slow = kfast.models.constant_velocity(2, 0.1, q=0.01, r=0.5)
    imm = kfast.imm_filter([model, slow], [[0.95, 0.05], [0.05, 0.95]], y, x0, P0)
    ax = kfast.plot.plot_mode_probabilities(imm, labels=["agile", "slow"])
    stacks = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(stacks) == 2
    top = stacks[1].get_paths()[0].vertices[:, 1].max()
    assert top == pytest.approx(1.0)

    nm = kfast.NonlinearModel.from_linear(model)
    pf = nm.particle_filter(y, x0, P0, 400, seed=1, keep="last")
    ax = kfast.plot.plot_particles(pf, truth=truth[-1])
    cloud = [c for c in ax.collections if isinstance(c, PathCollection)][0]
    assert len(cloud.get_offsets()) == 400
    w = np.exp(pf.log_weights)
    np.testing.assert_allclose(cloud.get_sizes(), np.maximum(w * 400 * 6.0, 0.5))
    ax = kfast.plot.plot_particles(np.random.default_rng(0).normal(size=(300, 2)), dims=[0])
    assert len(ax.patches) > 0  # a histogram


def test_demo_writes_a_png(tmp_path):
    model, x0, P0, truth, y = cv_run(T=120)
    path = tmp_path / "demo.png"
    fig = write_demo_plot(str(path), model, truth, y, x0, P0)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 20_000
    track, vx, vy = fig.subfigs[0].axes[0], fig.subfigs[1].axes[0], fig.subfigs[1].axes[1]
    assert sum(isinstance(p, Ellipse) for p in track.patches) == 20  # every 5th of the first 100 steps
    assert vx.get_ylabel() == "velocity x" and vy.get_ylabel() == "velocity y"


def test_bad_input():
    model, x0, P0, truth, y = cv_run(T=20)
    res = model.filter(y, x0, P0)
    with pytest.raises(ValueError, match="components: 7 is not a state component"):
        kfast.plot.plot_estimates(res, components=[7])
    with pytest.raises(ValueError, match="level: expected a probability"):
        kfast.plot.plot_estimates(res, level=1.5)
    with pytest.raises(ValueError, match=r"truth: expected shape \(20, 4\)"):
        kfast.plot.plot_estimates(res, truth=truth[:5])
    with pytest.raises(ValueError, match="dims: expected two different state components"):
        kfast.plot.plot_track(res, dims=(0, 0))
    with pytest.raises(ValueError, match=r"window: expected 0 <= start < stop <= 20"):
        kfast.plot.plot_track(res, window=(5, 40))
    with pytest.raises(ValueError, match="every: expected a positive integer"):
        kfast.plot.plot_track(res, every=0)
    with pytest.raises(ValueError, match="result: expected a result with x_filt"):
        kfast.plot.plot_estimates(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="labels: expected 2 labels"):
        kfast.plot.plot_mode_probabilities(np.full((4, 2), 0.5), labels=["a"])
    with pytest.raises(ValueError, match="particles: the ParticleResult kept no particles"):
        pf = kfast.NonlinearModel.from_linear(model).particle_filter(y, x0, P0, 50)
        kfast.plot.plot_particles(pf)
    with pytest.raises(ValueError, match="weights: expected 3 finite nonnegative weights"):
        kfast.plot.plot_particles(np.zeros((3, 2)), weights=[1.0, -1.0, 1.0])
    before = y.copy()
    kfast.plot.plot_estimates(res, y=y, observed=[0, 1])
    np.testing.assert_array_equal(y, before)
