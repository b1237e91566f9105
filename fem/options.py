"""The FEA's named choices, declared without their implementations: `FeaSettings` checks a run's
element order and linear solver against these names in `pipeline.py`'s own process before the FEA's
process starts, and importing the modules that implement them (scikit-fem, SciPy's sparse
matrices) took 0.3 s of that start (`python -X importtime pipeline.py`).

fem.problem.ELEMENTS and fem.solvers.SOLVERS implement these names (tests/test_startup.py checks
that they agree).
"""

from __future__ import annotations

from .errors import FemError

ELEMENT_ORDERS = (1, 2)  # P1 / P2 tetrahedra (fem.problem.ELEMENTS)
LINEAR_SOLVERS = ("pardiso", "amg", "spsolve")  # fem.solvers.SOLVERS; "auto" picks one of them


def check_element_order(order: int) -> None:
    """Refuse an order that fem.problem.ELEMENTS does not implement, in the bad-input form."""
    if order not in ELEMENT_ORDERS:
        expected = ", ".join(map(str, ELEMENT_ORDERS))
        raise FemError(f"element order {order!r}: expected one of {expected} (P1 / P2 tetrahedra); set it with --order")


def check_linear_solver(method: str) -> None:
    """Refuse a linear solver that fem.solvers.SOLVERS does not implement, in the bad-input form."""
    if method != "auto" and method not in LINEAR_SOLVERS:
        expected = ", ".join(("auto", *LINEAR_SOLVERS))
        raise FemError(f"linear solver {method!r}: expected one of {expected}; set it with python -m fem --solver")
