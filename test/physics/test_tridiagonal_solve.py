"""The kernel's linear solve of the Newton system (tridiagonal, symmetric positive definite)."""
import numpy as np
import pytest

from ltd_brake_ros.physics.newton import _solve_tridiagonal


def dense(dvec, cj):
    """J = diag(dvec) + sum over couplers j of cj (e_j - e_j+1)(e_j - e_j+1)^T."""
    n = dvec.size
    jac = np.diag(dvec)
    for j in range(n - 1):
        jac[j:j + 2, j:j + 2] += cj[j] * np.array([[1.0, -1.0], [-1.0, 1.0]])
    return jac


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 32, 33, 1001])
def test_solves_the_newton_system_to_round_off(n):
    # vehicle terms rho M / (beta h) of a 10 ms step (1e6-1e8 N s/m) against couplers from
    # slack (0) to the stiffest table segment times beta h plus the band's rate term (1e9)
    rng = np.random.default_rng(n)
    for _ in range(10):
        dvec = rng.uniform(1e6, 1e8, n)
        cj = np.where(rng.uniform(size=max(n - 1, 1)) < 0.2, 0.0,
                      10.0 ** rng.uniform(3.0, 9.0, max(n - 1, 1)))
        g = rng.normal(0.0, 1e5, n)
        du, work = np.empty(n), np.empty(n)
        _solve_tridiagonal(dvec, cj, g, work, du)
        jac = dense(dvec, cj[:n - 1])
        # backward stable: the residual is round-off of the terms that make it up
        scale = (np.abs(jac) @ np.abs(du)).max() + np.abs(g).max()
        assert np.abs(jac @ du + g).max() <= 1e-14 * scale
