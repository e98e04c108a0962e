"""Polynomial methods (Söderström ch. 4 and 7): polynomials are 1-D coefficient arrays in
descending powers of q (or z), NumPy's ``poly1d`` order; A, C and spectral factors are monic;
an ARMA(X) model is A(q) y = B(q) u + C(q) e, var e = λ².

- :func:`spectral_factor` — λ² B B* (/ A A*) of a rational spectrum, by the zeros or by the
  Riccati equation (Thm 4.2); the two routes agree.
- :func:`diophantine` — A X + B Y = C (the Sylvester system); :func:`predictor_identity` —
  z^(k-1) C = A F + L (7.13); :func:`causal_part` — [G / (D P*)]_+ by the two-sided
  Diophantine equation (7.64)-(7.70).
- :func:`arma_predictor` — the k-step predictor q L / C (7.18), with C's zeros reflected into
  the unit circle first (:func:`invertible`, Example 7.1).
- :func:`varmax_predictor` — the general multivariable k-step predictor (7.24)-(7.31) of
  A(q) y = B(q) u + C(q) e with matrix polynomials.
- :func:`wiener_causal`, :func:`wiener_noncausal`, :func:`wiener_fir` — Wiener filters of a
  signal C/A v in coloured noise M/N e, lag m (7.47), (7.76)-(7.93).
- :func:`arma_to_ss`, :func:`ss_to_arma` — ARMA(X) <-> innovations state space, so each
  result can be checked against the Kalman filter.
- arithmetic: :func:`polymul`, :func:`polyadd`, :func:`polysub`, :func:`reciprocal`,
  :func:`laurent` (A(z) B(z^-1)).
"""

from kfast.poly._poly import laurent, polyadd, polymul, polysub, reciprocal
from kfast.poly.arma import ArmaPredictor, arma_predictor, arma_to_ss, invertible, ss_to_arma
from kfast.poly.equations import Diophantine, causal_part, diophantine, predictor_identity
from kfast.poly.varmax import VarmaxPredictor, varmax_predictor
from kfast.poly.spectral import SpectralFactor, evaluate_spectrum, spectral_factor
from kfast.poly.wiener import WienerFilter, wiener_causal, wiener_fir, wiener_noncausal

__all__ = [
    "spectral_factor",
    "evaluate_spectrum",
    "diophantine",
    "predictor_identity",
    "causal_part",
    "arma_predictor",
    "invertible",
    "arma_to_ss",
    "ss_to_arma",
    "polymul",
    "polyadd",
    "polysub",
    "reciprocal",
    "laurent",
    "SpectralFactor",
    "Diophantine",
    "ArmaPredictor",
    "varmax_predictor",
    "VarmaxPredictor",
    "wiener_causal",
    "wiener_noncausal",
    "wiener_fir",
    "WienerFilter",
]
