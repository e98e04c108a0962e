"""Plain NumPy reference implementations: short, textbook-readable, the oracle for tests.

Never imported by the fast path. Each function cites the equations it implements.
"""

from kfast.reference.filter import kalman_filter

__all__ = ["kalman_filter"]
