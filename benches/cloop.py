"""Build and load the plain C Kalman loop (benches/c/kf_cv.c) with ctypes.

    from cloop import CLoop
    c = CLoop.build()            # gcc -O3 -march=native -shared -fPIC into a temp dir
    c128 = CLoop.build(flags=("-O3", "-march=native", "-mprefer-vector-width=128"))
    x_filt, P_filt, ll = c.filter(F, H, Q, R, y, x0, P0)
    ll = c.loglik(F, H, Q, R, y, x0, P0)
    x_s, P_s, ll = c.smooth(F, H, Q, R, y, x0, P0)     # RTS smoother (W2)

`CLoop.build()` raises RuntimeError (with the compiler's message) if gcc is
missing or the build fails; the benchmark catches that and reports the C
column as unavailable.  Every build goes into its own temp dir, so builds
with different sizes or flags never share a .so (nor a dlopen handle).
"""

from __future__ import annotations

import atexit
import ctypes
import os
import shutil
import subprocess
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(HERE, "c", "kf_cv.c")
# The optimisation flags of the reference C loop (issue #11: kfast is compared
# with gcc -O3 -march=native).  Other flag sets are extra rows beside it.
DEFAULT_FLAGS = ("-O3", "-march=native")

_dp = ctypes.POINTER(ctypes.c_double)


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_dp)


def _c64(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


class CLoop:
    def __init__(self, lib: ctypes.CDLL, cc_cmd: str, tmpdir: str, flags=DEFAULT_FLAGS):
        self.lib = lib
        self.cc_cmd = cc_cmd
        self.flags = tuple(flags)
        self._tmpdir = tmpdir
        self.n = lib.kf_cv_n()
        self.m = lib.kf_cv_m()
        args = [_dp, _dp, _dp, _dp, _dp, ctypes.c_long, _dp, _dp]
        lib.kf_cv_filter.argtypes = args + [_dp, _dp]
        lib.kf_cv_filter.restype = ctypes.c_double
        lib.kf_cv_loglik.argtypes = args
        lib.kf_cv_loglik.restype = ctypes.c_double
        lib.kf_cv_smooth.argtypes = args + [_dp, _dp, _dp, _dp]
        lib.kf_cv_smooth.restype = ctypes.c_double

    @classmethod
    def build(cls, n: int = 4, m: int = 2, cc: str | None = None, flags=DEFAULT_FLAGS) -> "CLoop":
        """Compile kf_cv.c with N=n, M=m and the optimisation `flags`."""
        cc = cc or os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
        if not cc:
            raise RuntimeError("no C compiler (gcc/cc) on PATH")
        tmpdir = tempfile.mkdtemp(prefix="kfast_bench_c_")
        atexit.register(shutil.rmtree, tmpdir, True)
        so = os.path.join(tmpdir, "libkf_cv.so")
        cmd = [cc, *flags, "-shared", "-fPIC", f"-DN={n}", f"-DM={m}", SRC, "-o", so, "-lm"]
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        except Exception as e:  # noqa: BLE001
            raise RuntimeError(f"C build failed: {e}") from e
        if p.returncode != 0:
            raise RuntimeError("C build failed:\n" + " ".join(cmd) + "\n" + p.stderr)
        lib = ctypes.CDLL(so)
        shown = cmd[: len(flags) + 3]  # compiler, flags, -shared -fPIC
        return cls(lib, " ".join(os.path.basename(c) if c == cc else c for c in shown), tmpdir, flags)

    def close(self):
        shutil.rmtree(self._tmpdir, ignore_errors=True)

    # --- calls -----------------------------------------------------------
    def prepare(self, F, H, Q, R, y, x0, P0):
        """Convert once to contiguous float64 so timing covers only the call."""
        y = _c64(y)
        assert y.ndim == 2 and y.shape[1] == self.m
        return [_c64(F), _c64(H), _c64(Q), _c64(R), y, _c64(x0), _c64(P0)]

    def filter_prepared(self, args, out=None):
        F, H, Q, R, y, x0, P0 = args
        T = y.shape[0]
        if out is None:
            out = (np.empty((T, self.n)), np.empty((T, self.n, self.n)))
        xf, Pf = out
        ll = self.lib.kf_cv_filter(_ptr(F), _ptr(H), _ptr(Q), _ptr(R), _ptr(y), T,
                                   _ptr(x0), _ptr(P0), _ptr(xf), _ptr(Pf))
        return xf, Pf, ll

    def loglik_prepared(self, args):
        F, H, Q, R, y, x0, P0 = args
        return self.lib.kf_cv_loglik(_ptr(F), _ptr(H), _ptr(Q), _ptr(R), _ptr(y),
                                     y.shape[0], _ptr(x0), _ptr(P0))

    def smooth_out(self, T):
        """(x_s, P_s, x_pred, P_pred): outputs plus the forward-pass work buffers."""
        n = self.n
        return (np.empty((T, n)), np.empty((T, n, n)), np.empty((T, n)), np.empty((T, n, n)))

    def smooth_prepared(self, args, out=None):
        """RTS smoother.  Returns (x_smooth (T,n), P_smooth (T,n,n), loglik).

        `out` = smooth_out(T) to reuse buffers; by default all four are
        allocated fresh on every call (the priors buffers are part of the
        cost: the backward pass needs x(t+1|t), P(t+1|t))."""
        F, H, Q, R, y, x0, P0 = args
        T = y.shape[0]
        if out is None:
            out = self.smooth_out(T)
        xs, Ps, xp, Pp = out
        ll = self.lib.kf_cv_smooth(_ptr(F), _ptr(H), _ptr(Q), _ptr(R), _ptr(y), T,
                                   _ptr(x0), _ptr(P0), _ptr(xs), _ptr(Ps), _ptr(xp), _ptr(Pp))
        return xs, Ps, ll

    def smooth(self, F, H, Q, R, y, x0, P0):
        return self.smooth_prepared(self.prepare(F, H, Q, R, y, x0, P0))

    def filter(self, F, H, Q, R, y, x0, P0):
        return self.filter_prepared(self.prepare(F, H, Q, R, y, x0, P0))

    def loglik(self, F, H, Q, R, y, x0, P0):
        return self.loglik_prepared(self.prepare(F, H, Q, R, y, x0, P0))
