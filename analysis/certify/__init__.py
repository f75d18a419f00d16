"""Certificates of a switched system, each re-checked outside the tool that produced it: the one module to import.

Stability of your own system: :func:`analyse_stability` (equilibria against their modes, LMI certificates,
regions of attraction, limit cycles) or its pieces — :func:`common_quadratic_lyapunov_lmi`,
:func:`dwell_time_lyapunov`, :func:`piecewise_quadratic_lyapunov` (LMIs re-checked in exact arithmetic,
:mod:`analysis.exact`), :func:`mode_region_of_attraction` (a mode's region of attraction proven by interval
branch and bound), :func:`sos_lyapunov` and :func:`region_of_attraction` (sums of squares),
:func:`certify_nonpositive` and :func:`certify_sublevel` (sign and sublevel-set claims by branch and bound),
:func:`mode_equilibria`, :func:`linearise`, :func:`periodic_orbit` (shooting, saltation, Floquet).  Sound
interval arithmetic: :class:`Interval`; exact rationals: :func:`rational`.

The modules behind it stay importable for the finer pieces (``analysis.lmi``, ``analysis.sos``, ...).
"""

from analysis.certificate import certify_nonpositive
from analysis.equilibria import mode_equilibria
from analysis.exact import rational
from analysis.interval import Interval
from analysis.linearise import linearise
from analysis.lmi import common_quadratic_lyapunov_lmi, dwell_time_lyapunov, piecewise_quadratic_lyapunov
from analysis.mode_region import mode_region_of_attraction
from analysis.periodic import periodic_orbit
from analysis.sos import region_of_attraction, sos_lyapunov
from analysis.stability import analyse_stability
from analysis.sublevel import certify_sublevel

__all__ = [
    "analyse_stability",
    "common_quadratic_lyapunov_lmi",
    "dwell_time_lyapunov",
    "piecewise_quadratic_lyapunov",
    "mode_region_of_attraction",
    "sos_lyapunov",
    "region_of_attraction",
    "certify_nonpositive",
    "certify_sublevel",
    "mode_equilibria",
    "linearise",
    "periodic_orbit",
    "Interval",
    "rational",
]
