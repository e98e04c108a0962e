"""The package and its stub for the compiled module type-check (mypy), and code using the
public API type-checks against them."""

import textwrap

from mypy import api

USER_CODE = textwrap.dedent(
    """
    import numpy as np
    import kfast

    m = kfast.LinearGaussian(np.eye(2), np.eye(2), np.eye(2), np.eye(2))
    r: kfast.FilterResult = m.filter(np.zeros((3, 2)), np.zeros(2), np.eye(2))
    s: kfast.SmootherResult = m.smooth(np.zeros((3, 2)), np.zeros(2), np.eye(2))
    f: kfast.Forecast = r.forecast(3)
    kf = kfast.KalmanFilter(m, np.zeros(2), np.eye(2))
    kf.update([0.0, 1.0])
    kf.predict()
    x: np.ndarray = kf.x
    lagged = kfast.FixedLagSmoother(m, np.zeros(2), np.eye(2), 2).x_lagged
    ll: float = m.loglik(np.zeros((3, 2)), np.zeros(2), np.eye(2))
    """
)


def test_package_and_user_code_type_check(tmp_path):
    # -p kfast: check the installed package as a package (a path inside site-packages would
    # make mypy treat site-packages as a source root).
    user = tmp_path / "user.py"
    user.write_text(USER_CODE)
    stdout, stderr, status = api.run(
        ["-p", "kfast", "--ignore-missing-imports", "--cache-dir", str(tmp_path / "cache")]
    )
    assert status == 0, stdout + stderr
    stdout, stderr, status = api.run([str(user), "--ignore-missing-imports", "--cache-dir", str(tmp_path / "cache")])
    assert status == 0, stdout + stderr


def test_wrong_use_is_caught(tmp_path):
    user = tmp_path / "wrong.py"
    user.write_text("import kfast\nkf = kfast.KalmanFilter()\nkf.x.no_such_attribute\n")
    stdout, _, status = api.run([str(user), "--ignore-missing-imports", "--cache-dir", str(tmp_path / "cache")])
    assert status == 1 and "KalmanFilter" in stdout
