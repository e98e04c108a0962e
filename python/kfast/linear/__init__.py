"""Linear Gaussian state-space models: the model and its filter, smoothers, forecasts and
simulation (``model``), parameter estimation (``estimation``: maximum likelihood and EM) and
many series at once (``batch``). The Rust side is ``rust/src/linear/``."""
