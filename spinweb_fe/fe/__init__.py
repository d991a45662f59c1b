"""The explicit solver's data and step: model, state, control laws, numba kernels."""
