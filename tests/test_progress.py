"""progress=True of filter_batch, fit and EM: reports on stderr, the same results bit for bit."""

import numpy as np
import pytest

import kfast


def cv_batch(B=45, T=40, missing=False):
    model = kfast.models.constant_velocity(1, 0.1, q=1.0, r=0.5)
    x0, P0 = np.zeros(2), np.eye(2)
    Y = np.stack([model.simulate(T, x0, P0, seed=s)[1] for s in range(B)])
    if missing:
        Y[7, 3] = np.nan
    return model, x0, P0, Y


@pytest.mark.parametrize("missing", [False, True])
@pytest.mark.parametrize("per_series_prior", [False, True])
def test_filter_batch_with_progress_is_the_same(capsys, missing, per_series_prior):
    model, x0, P0, Y = cv_batch(missing=missing)
    X0 = np.tile(x0, (len(Y), 1)) + np.arange(len(Y))[:, None] * 0.01 if per_series_prior else x0
    plain = kfast.filter_batch(model, Y, X0, P0)
    reported = kfast.filter_batch(model, Y, X0, P0, progress=True)
    for name in ("x_filt", "P_filt", "loglik"):
        np.testing.assert_array_equal(getattr(reported, name), getattr(plain, name))
    assert reported.shared_covariance == plain.shared_covariance
    assert "filter_batch" in capsys.readouterr().err


def test_fit_and_em_report_progress(capsys):
    model, x0, P0, Y = cv_batch(B=1, T=200)
    y = Y[0]

    def build(theta):
        return kfast.models.constant_velocity(1, 0.1, q=float(np.exp(theta[0])), r=float(np.exp(theta[1]))), x0, P0

    plain = kfast.fit(build, np.zeros(2), y)
    capsys.readouterr()
    reported = kfast.fit(build, np.zeros(2), y, progress=True)
    np.testing.assert_array_equal(reported.theta, plain.theta)
    err = capsys.readouterr().err
    assert "fit" in err and "loglik" in err
    res = model.em(y, x0, P0, n_iter=3, progress=True)
    err = capsys.readouterr().err
    assert "EM" in err and res.n_iter == 3
    with pytest.raises(ValueError, match="progress"):
        kfast.filter_batch(model, Y, x0, P0, progress="yes")
