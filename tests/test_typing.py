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
    # the options as literals, array-likes for arrays
    r2 = m.filter([[0.0, 1.0]], [0.0, 0.0], [[1.0, 0.0], [0.0, 1.0]], form="standard", outputs=("x_filt", "S"))
    s2 = m.smooth(np.zeros((3, 2)), np.zeros(2), np.eye(2), form="joseph", outputs="x_smooth")
    kf2 = kfast.KalmanFilter(m, [0.0, 0.0], np.eye(2), form="standard")
    kf2.update([0.0, 1.0], H=np.eye(2), R=[[2.0, 0.0], [0.0, 1.0]])
    kf2.predict()
    kf2.step([0.0, 1.0], R=np.eye(2))
    X: np.ndarray = kfast.solve_discrete_are(np.eye(2), np.eye(2), np.eye(2), np.eye(2), method="newton")
    ss = m.steady_state(method="eigen")
    b = kfast.filter_batch(m, np.zeros((4, 3, 2)), np.zeros(2), np.eye(2), form="standard")
    e = m.em(np.zeros((3, 2)), np.zeros(2), np.eye(2), n_iter=1, fit=("Q", "R"))
    ct = kfast.models.coordinated_turn(0.1, q=1.0, sigma_omega=0.05)
    nm = kfast.NonlinearModel(ct, kfast.models.range_bearing((0.0, 0.0)), np.eye(5), np.eye(2), n=5)
    nr: kfast.FilterResult = nm.ekf(np.zeros((3, 2)), np.ones(5), np.eye(5), iterations=2, iteration="gauss-newton")
    ur: kfast.FilterResult = nm.ukf(np.zeros((3, 2)), np.ones(5), np.eye(5), points=kfast.sigma.cubature(), outputs="x_filt")
    """
)

# Each must fail type checking, with the given text in mypy's message.
WRONG_CODE = {
    "filter_form": ('m.filter(np.zeros((3, 2)), np.zeros(2), np.eye(2), form="josef")', "josef"),
    "smooth_form": ('m.smooth(np.zeros((3, 2)), np.zeros(2), np.eye(2), form="Joseph")', "Joseph"),
    "streaming_form": ('kfast.KalmanFilter(m, np.zeros(2), np.eye(2), form="josef")', "josef"),
    "batch_form": ('kfast.filter_batch(m, np.zeros((4, 3, 2)), np.zeros(2), np.eye(2), form="josef")', "josef"),
    "dare_method": ('kfast.solve_discrete_are(np.eye(2), np.eye(2), np.eye(2), np.eye(2), method="dubling")', "dubling"),
    "steady_state_method": ('m.steady_state(method="schur")', "schur"),
    "output_name": ('m.filter(np.zeros((3, 2)), np.zeros(2), np.eye(2), outputs=("x_flit",))', "x_flit"),
    "em_parameter": ('m.em(np.zeros((3, 2)), np.zeros(2), np.eye(2), fit=("F", "G"))', "Literal['G']"),
    "streaming_model": ("kfast.KalmanFilter(np.eye(2), np.zeros(2), np.eye(2))", "KalmanFilter"),
    "ekf_iteration": ('kfast.NonlinearModel(lambda X, t, u: X, lambda X, t, u: X, np.eye(2), np.eye(2), n=2).ekf(np.zeros((3, 2)), np.zeros(2), np.eye(2), iteration="newton")', "newton"),
    "positional_R": ("kfast.KalmanFilter(m, np.zeros(2), np.eye(2)).update([0.0, 1.0], None, np.eye(2))", "update"),
}


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
    exec(compile(USER_CODE, "user.py", "exec"), {})  # and it runs: the types are not stricter than kfast


def test_wrong_use_is_caught(tmp_path):
    user = tmp_path / "wrong.py"
    user.write_text("import kfast\nkf = kfast.KalmanFilter()\nkf.x.no_such_attribute\n")
    stdout, _, status = api.run([str(user), "--ignore-missing-imports", "--cache-dir", str(tmp_path / "cache")])
    assert status == 1 and "KalmanFilter" in stdout


def test_misspelt_options_fail_type_checking(tmp_path):
    header = "import numpy as np\nimport kfast\nm = kfast.LinearGaussian(np.eye(2), np.eye(2), np.eye(2), np.eye(2))\n"
    files = {}
    for name, (line, _) in WRONG_CODE.items():
        files[name] = tmp_path / f"wrong_{name}.py"
        files[name].write_text(header + line + "\n")
    stdout, _, status = api.run(
        [str(f) for f in files.values()] + ["--ignore-missing-imports", "--cache-dir", str(tmp_path / "cache")]
    )
    assert status == 1, stdout
    for name, (_, text) in WRONG_CODE.items():
        errors = [ln for ln in stdout.splitlines() if f"wrong_{name}.py:4: error" in ln]
        assert errors and any(text in ln for ln in errors), f"{name}: {errors or stdout}"
