"""The explicit solver's data and step: model, state, control laws, numba kernels."""

from spinweb_fe.fe import cache  # noqa: F401 - the cache locators, before any kernel is defined
