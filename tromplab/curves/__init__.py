"""Separation curves: the formula registry, fitting (lmfit and the batched engine), screening, residual diagnostics, ranking, indices."""
