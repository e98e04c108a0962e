"""Run fuzz cases in a child process, so that a crash, a hang or a memory blow-up is recorded
as a failure instead of taking the test run down.

The worker is ``python isolation.py`` (this file run as a script). It limits its own address
space (``resource.setrlimit(RLIMIT_AS)``, 4 GiB by default), then reads pickled cases from stdin
and writes pickled outcomes to stdout, one length-prefixed message each. The parent waits for
each answer with a timeout; when the worker dies (a segfault, an abort on a failed allocation)
the case is a ``crash``, when it does not answer in time the worker is killed (by its own pid)
and the case is a ``hang``; either way a new worker is started for the next case. The tail of
the worker's stderr (e.g. a Rust panic message) goes into the failure's detail.

``KFAST_FUZZ_LOG``: when set, every outcome is appended to that file as one JSON line (the
report script, tests/fuzz/report.py, reads it).
"""

from __future__ import annotations

import json
import os
import pickle
import select
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ADDRESS_SPACE_LIMIT = int(os.environ.get("KFAST_FUZZ_AS_LIMIT", 4 << 30))


def _write(stream, obj) -> None:
    data = pickle.dumps(obj)
    stream.write(struct.pack("<Q", len(data)) + data)
    stream.flush()


def _read_exact(fd: int, n: int, deadline: float) -> bytes:
    chunks = []
    while n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError
        ready, _, _ = select.select([fd], [], [], left)
        if not ready:
            raise TimeoutError
        chunk = os.read(fd, n)
        if not chunk:
            raise EOFError
        chunks.append(chunk)
        n -= len(chunk)
    return b"".join(chunks)


class Worker:
    """A child process that runs cases; restarted after a crash or a hang."""

    def __init__(self, timeout: float = 10.0):
        self.timeout = timeout
        self.proc = None
        self.log = os.environ.get("KFAST_FUZZ_LOG")

    def _start(self) -> None:
        self.stderr = tempfile.TemporaryFile()
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", PYTHONFAULTHANDLER="1")
        self.proc = subprocess.Popen(
            [sys.executable, str(HERE / "isolation.py")], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.stderr, env=env
        )
        ready = self._receive(60.0)
        assert ready == "ready", ready

    def _receive(self, timeout: float):
        deadline = time.monotonic() + timeout
        fd = self.proc.stdout.fileno()
        (n,) = struct.unpack("<Q", _read_exact(fd, 8, deadline))
        return pickle.loads(_read_exact(fd, n, deadline))

    def _stderr_tail(self) -> str:
        self.stderr.seek(0)
        lines = [ln for ln in self.stderr.read().decode(errors="replace").splitlines() if ln.strip()]
        return " | ".join(lines[-4:])[-600:]

    def _kill(self) -> None:
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.wait()
            self.proc.stdout.close()
            self.proc.stdin.close()
            self.proc = None

    def run(self, case, timeout: float = None) -> dict:
        """The outcome of one case (fuzzcases.run_case, or crash / hang)."""
        if self.proc is None:
            self._start()
        started = time.monotonic()
        try:
            _write(self.proc.stdin, case)
            outcome = self._receive(timeout or self.timeout)
        except TimeoutError:
            self._kill()
            outcome = {"outcome": "failure", "kind": "hang", "detail": f"no answer within {timeout or self.timeout:.0f} s"}
        except (EOFError, BrokenPipeError):
            code = self.proc.wait()
            tail = self._stderr_tail()
            self._kill()
            outcome = {"outcome": "failure", "kind": "crash", "detail": f"the worker died (exit code {code}): {tail}"}
        outcome["seconds"] = round(time.monotonic() - started, 4)
        if self.log:
            record = dict(outcome, entry=case.entry, family=case.family, variant=case.variant, arg=case.perturbed, repro=case.repro())
            with open(self.log, "a") as f:
                f.write(json.dumps(record) + "\n")
        return outcome

    def close(self) -> None:
        self._kill()


def format_failure(case, outcome: dict) -> str:
    return (
        f"[{outcome['kind']}] {case.entry} / {case.perturbed} / {case.family}: {case.variant} (expected {case.expect})\n"
        f"    {outcome['detail']}\n"
        f"    repro: python -c \"{case.repro()}\""
    )


def _serve() -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE_LIMIT, ADDRESS_SPACE_LIMIT))
    sys.path.insert(0, str(HERE))
    import warnings

    warnings.simplefilter("ignore")
    import fuzzcases

    out = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    sys.stdout = sys.stderr  # nothing the library prints can corrupt the protocol
    stdin = sys.stdin.buffer
    _write(out, "ready")
    while True:
        head = stdin.read(8)
        if len(head) < 8:
            return
        (n,) = struct.unpack("<Q", head)
        case = pickle.loads(stdin.read(n))
        try:
            outcome = fuzzcases.run_case(case)
        except BaseException as exc:  # noqa: B036 - the classifier itself must never kill the worker
            outcome = {"outcome": "failure", "kind": "panic" if not isinstance(exc, Exception) else "campaign-bug", "detail": repr(exc)[:300]}
        _write(out, outcome)


if __name__ == "__main__":
    _serve()


def run_strategy(strategy, worker, fuzz_settings) -> tuple[list, int]:
    """Runs every distinct case Hypothesis draws from ``strategy`` in ``worker``; returns the
    formatted failures and the number of cases tried (``KFAST_FUZZ_SEED`` picks other cases)."""
    from hypothesis import given, seed, settings

    failures, seen = [], set()

    @settings(fuzz_settings)
    @given(strategy)
    def run(case):
        if case.key() in seen:
            return
        seen.add(case.key())
        outcome = worker.run(case)
        if outcome["outcome"] == "failure":
            failures.append(format_failure(case, outcome))

    if os.environ.get("KFAST_FUZZ_SEED"):
        run = seed(int(os.environ["KFAST_FUZZ_SEED"]))(run)
    run()
    return failures, len(seen)
