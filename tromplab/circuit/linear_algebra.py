"""The few :mod:`scipy.linalg` functions a reconciliation of a small flowsheet and a survey
design call, computed with numpy's LAPACK; every other name is :mod:`scipy.linalg`'s.

``import scipy.linalg`` imports scipy's array-API layer, which imports ``numpy.f2py`` and
``numpy.testing``: about 70 ms of a ``tromplab circuit design`` that takes 0.6 s on a quiet
machine, for a null space and a few Cholesky solves of at most a few dozen rows.  The modules
of the circuit import this one under the name ``linalg``: :func:`null_space`, :func:`cho_factor`
and :func:`cho_solve` are here, with scipy's signatures and algorithms; any other attribute
(the pivoted QR of a large flowsheet's bounds) imports :mod:`scipy.linalg` on first use and is
its function.  :data:`sparse` is :mod:`scipy.sparse`, imported when a large flowsheet first
reads one of its names (70 ms of start-up a small one does not pay).

:func:`null_space` is scipy's algorithm on the same LAPACK routine (``gesdd``), and gives the
same bits on the surveys of ``tests/data/circuit_reference``; the Cholesky solves differ from
LAPACK's ``potrs`` in the order of their sums (a few units of 1e-14 relative on the design
candidates of the bundled example, each the solve of ``I + E C E^T``, whose eigenvalues are 1 or
more).  ``tests/test_circuit_linear_algebra.py`` compares each with :mod:`scipy.linalg`.
"""

from __future__ import annotations

import importlib

import numpy as np

__all__ = ["cho_factor", "cho_solve", "null_space", "sparse"]


def null_space(A: np.ndarray, rcond: float | None = None) -> np.ndarray:
    """Orthonormal basis of the null space of ``A`` (columns), from its singular value
    decomposition: the right singular vectors of the singular values at most ``rcond`` times
    the largest (default: the machine epsilon times the larger dimension), as
    ``scipy.linalg.null_space``."""
    _, singular, vh = np.linalg.svd(A, full_matrices=True)
    if rcond is None:
        rcond = np.finfo(singular.dtype).eps * max(A.shape)
    rank = int(np.sum(singular > np.amax(singular, initial=0.0) * rcond))
    # rows in memory order, as scipy's (a view of LAPACK's Fortran array): the products with the
    # basis then take the same BLAS paths, and the reconciliation the same bits (numpy's basis
    # is column-major, which moved an assayed survey's adjustments by 2e-5 relative)
    return np.ascontiguousarray(vh[rank:, :].T.conj())


def cho_factor(a: np.ndarray) -> tuple[np.ndarray, bool]:
    """``(L, True)``: the lower Cholesky factor of the symmetric positive-definite ``a``
    (``a = L L^T``), for :func:`cho_solve`; ``numpy.linalg.LinAlgError`` (which
    ``scipy.linalg.LinAlgError`` is) when ``a`` is not positive definite."""
    return np.linalg.cholesky(a), True


def cho_solve(factor: tuple[np.ndarray, bool], b: np.ndarray) -> np.ndarray:
    """The solution ``x`` of ``a x = b`` from ``factor = cho_factor(a)``, by forward and back
    substitution (one row of ``x`` at a time, every column of ``b`` at once)."""
    lower, is_lower = factor
    if not is_lower:
        raise ValueError("cho_solve takes the factor of tromplab.circuit.linear_algebra.cho_factor (lower)")
    x = np.array(b, dtype=float)  # a copy: solved in place
    size = lower.shape[0]
    for i in range(size):
        x[i] = (x[i] - lower[i, :i] @ x[:i]) / lower[i, i]
    for i in reversed(range(size)):
        x[i] = (x[i] - lower[i + 1 :, i] @ x[i + 1 :]) / lower[i, i]
    return x


class _ImportedOnFirstUse:
    """Stands for a module until one of its names is read, then imports it and reads the name there."""

    def __init__(self, module: str):
        self._module = module

    def __getattr__(self, name: str):
        if name.startswith("__"):  # Python's own questions (copy, pickle, inspect) import nothing
            raise AttributeError(name)
        return getattr(importlib.import_module(self._module), name)


#: :mod:`scipy.sparse` for the modules of the circuit (``from .linear_algebra import sparse``):
#: imported when a flowsheet of :data:`~tromplab.circuit.problem.SPARSE_UNKNOWNS` unknowns or
#: more forms its first sparse matrix.
sparse = _ImportedOnFirstUse("scipy.sparse")


def __getattr__(name: str):
    # every other name is scipy.linalg's, imported when first asked for (a large flowsheet's
    # pivoted QR): a design or a small survey does not pay for the import.  Not the dunder
    # names the import system and doctest ask every module for: scipy.linalg's __path__ would
    # make this module look like a package
    if name.startswith("__"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module("scipy.linalg"), name)
