"""Integration formulas and their stability: the one module to import.

:func:`integrate` runs a scheme of :data:`SCHEMES` on an :class:`OdeProblem` (fixed-step BDF and
Runge-Kutta, with scipy's solvers as references); :func:`integrate_bdf` the project's fixed-step BDF with
its start-up; :func:`bdf_coefficients` their coefficients; :func:`stability_polynomial`, :func:`a_alpha`
and :func:`zero_stability` the formulas' stability regions; :func:`observed_order` the order a run shows.

The modules behind it (``analysis.bdf``, ``analysis.integrators``, ``analysis.integrator_regions``) stay
importable for the finer pieces.
"""

from analysis.bdf import bdf_coefficients, integrate_bdf
from analysis.integrator_regions import a_alpha, stability_polynomial, zero_stability
from analysis.integrators import SCHEMES, OdeProblem, integrate, observed_order

__all__ = [
    "SCHEMES",
    "OdeProblem",
    "integrate",
    "integrate_bdf",
    "bdf_coefficients",
    "stability_polynomial",
    "a_alpha",
    "zero_stability",
    "observed_order",
]
