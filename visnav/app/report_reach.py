"""The report's reachability proof of the sampled path-following loop, beside the SOS certificates.

:func:`bypass_reach_data` runs :func:`visnav.studies.path_following_reach.bypass_reach` (the campaign's
measured entries, then the flowpipe and its independent re-check) for the full report and returns its
data (rounded by :mod:`visnav.app.precision`: the proven bound up, the margin down) and its claims;
the quick report leaves it out and says so.  The data goes under ``analysis/path_following/bypass_reach``
of ``report.json`` and is rendered beside the SOS bounds (:mod:`visnav.app.report_render`).
"""

from __future__ import annotations

from typing import Any

from visnav.app.precision import KINDS, round_tree, round_value
from visnav.app.verification_report import Claim

__all__ = ["bypass_reach_data", "radius_inward"]

PATH = "analysis/path_following/bypass_reach"
"""Where the data sits in ``report.json`` (the precision rules' path)."""

_KEYS = ("k", "v_mps", "d_zero_m", "period_s", "radius_m", "entry_box", "coverage", "horizon_s", "time_step_s",
         "status", "margin_m", "delta_bound_m", "segments", "jumps")
"""The result's fields the report keeps: not the evidence text (raw floats) nor the wall clock."""


def bypass_reach_data(scenario: Any, *, samples: int, seed: int, run: bool) -> tuple[dict[str, Any], list[Claim]]:
    """The proof's data and claims (``run`` false: a ``"not run"`` entry, no claim).

    Parameters
    ----------
    scenario : visnav.parameters.Scenario
    samples, seed : int
        The campaign draws whose bypasses give the entries (the report's campaign budget and seed).
    run : bool
        Run the proof (the full report) or leave it out (the quick report).
    """
    if not run:
        return {"status": "not run", "why": "the quick report leaves out the sampled loop's flowpipe"}, []
    from visnav.studies.path_following_reach import bypass_reach

    result = bypass_reach(scenario, samples=samples, seed=seed).as_dict()
    data = round_tree({key: result[key] for key in _KEYS}, PATH)
    return data, _claims(data)


def radius_inward(radii: Any) -> tuple[float, float]:
    """The radii covered, printed with 4 significant digits rounded inward (a smaller range than proven)."""
    return round_value(radii[0], KINDS["bound_up"]), round_value(radii[1], KINDS["bound_down"])


def _claims(data: dict[str, Any]) -> list[Claim]:
    box, cov = data["entry_box"], data["coverage"]
    low, high = radius_inward(data["radius_m"])
    where = (f"delta in [{box['delta_m'][0]:.12g}, {box['delta_m'][1]:.12g}] m, alpha in "
             f"[{box['alpha_rad'][0]:.12g}, {box['alpha_rad'][1]:.12g}] rad, R in [{low:g}, {high:g}] m")
    loop = (f"the sampled path-following loop ({data['period_s'] * 1000:g} ms hold, k = {data['k']:g}, "
            f"v_coll = {data['v_mps']:g} m/s)")
    coverage = Claim(section="analysis", status="sampled", text=(
        f"sampled loop: the entry box holds {cov['inside']}/{cov['entries']} entries measured in {cov['samples']} "
        f"campaign draws (seed {cov['seed']}) and the window is the longest measured bypass "
        f"({cov['longest_bypass_s']:g} s): a sample of the campaign, not a proof of coverage"))
    if data["status"] != "proven":
        return [Claim(section="analysis", status="measured", text=(
            f"NOT PROVEN: |delta| < d0 = {data['d_zero_m']:g} m for {loop} from {where} over "
            f"[0, {data['horizon_s']:g}] s (the flowpipe or its re-check did not decide it)")), coverage]
    return [Claim(section="analysis", status="proven", text=(
        f"{loop} from {where}: |delta| <= {data['delta_bound_m']:g} m over [0, {data['horizon_s']:g}] s after entry "
        f"(margin >= {data['margin_m']:g} m to d0 = {data['d_zero_m']:g} m; flowpipe by conservative linearisation, "
        f"{data['segments']} segments, {data['jumps']} samples, re-checked independently)")), coverage]
