"""Figures of the stiffness study (:func:`visnav.studies.stiffness.stiffness_study`).

Rendering code only: the arrays come from :attr:`StiffnessStudy.plots`,
``data``/``timing`` and :func:`visnav.studies.stiffness.region_plot_data` (the root-modulus
grids and loci, computed only when a figure is drawn); this module draws them
(Agg backend, nothing shown) and returns the figures, which the CLI writes.
"""

from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from analysis.integrators import FIXED_STEP_SCHEMES, REFERENCE_SCHEMES  # noqa: E402

from visnav.studies.stiffness import StiffnessStudy, region_plot_data  # noqa: E402

__all__ = [
    "stability_regions_figure",
    "error_vs_step_figure",
    "error_vs_time_figure",
    "error_vs_evaluations_figure",
    "stiffness_ratio_figure",
    "stiffness_figures",
]

_COLORS = {
    "euler": "tab:gray", "rk4": "tab:red", "abm4": "tab:orange", "bdf1": "#08306b", "bdf2": "#08519c",
    "bdf3": "#2171b5", "bdf4": "#4292c6", "bdf5": "#6baed6", "bdf6": "#9ecae1", "scipy_bdf": "tab:green",
    "scipy_radau": "tab:olive", "scipy_lsoda": "tab:brown", "scipy_dop853": "tab:purple", "cvodes": "tab:pink",
}
_MARKERS = {"euler": "o", "rk4": "s", "abm4": "D"}


def _cloud(study: StiffnessStudy) -> tuple[np.ndarray, np.ndarray]:
    h = study.data["period_s"]
    paper = h * study.plots["paper_spectrum"].eigenvalues.reshape(-1)
    random = h * np.asarray(study.plots["random_cloud"]).reshape(-1)
    return paper, random


def stability_regions_figure(study: StiffnessStudy) -> Figure:
    """Stability regions (boundary ``max |ζ| = 1``) of every fixed scheme with the run's ``h λ`` cloud.

    Explicit schemes: contour ``max |ζ| = 1`` of the root-modulus grid; BDF:
    the boundary locus.  Left: the regions (explicit: inside; BDF: outside), the A(α)
    sectors of BDF3–6 and the BDF7 locus.  Right: zoom on the origin, where
    the whole ``h λ`` cloud of the run (blue) and of the random scenarios
    (grey) lies.
    """
    regions = region_plot_data(study.plots["region_zoom"])
    paper, random = _cloud(study)
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.4))
    for ax, view in zip(axes, ("global", "zoom")):
        grid = regions["views"][view]
        re, im = grid["re"], grid["im"]
        for scheme in ("euler", "rk4", "abm4"):
            ax.contour(re, im, grid["modulus"][scheme], levels=[1.0], colors=[_COLORS[scheme]], linewidths=1.2)
            ax.plot([], [], color=_COLORS[scheme], label=scheme)  # legend proxy for the contour
        for order in range(1, 7):
            locus = regions["loci"][f"bdf{order}"]
            if view == "zoom":  # keep the part near the origin (the locus is long and far away elsewhere)
                locus = np.where(np.abs(locus) < 4 * abs(re[0]), locus, np.nan)
            ax.plot(locus.real, locus.imag, color=_COLORS[f"bdf{order}"], lw=1.2, label=f"bdf{order}")
        if view == "global":
            locus = regions["loci"]["bdf7"]
            ax.plot(locus.real, locus.imag, color="k", lw=0.6, ls=":", label="bdf7 locus (not zero-stable)")
            for order, row in study.plots["a_alpha"].items():
                if order >= 3:
                    angle = np.radians(row["alpha_deg"])
                    r = 8.0
                    ax.plot([0, -r * np.cos(angle)], [0, r * np.sin(angle)], color=_COLORS[f"bdf{order}"], lw=0.6,
                            ls="--")
        if random.size:
            ax.scatter(random.real, random.imag, s=3, color="0.6", label="h λ, random scenarios", zorder=3)
        ax.scatter(paper.real, paper.imag, s=4, color="tab:blue", label="h λ, paper run", zorder=4)
        ax.axhline(0, color="k", lw=0.4)
        ax.axvline(0, color="k", lw=0.4)
        ax.set_xlim(re[0], re[-1])
        ax.set_ylim(im[0], im[-1])
        ax.set_xlabel("Re h λ")
        ax.set_ylabel("Im h λ")
        ax.set_aspect("equal")
        ax.grid(True, lw=0.3)
    axes[0].set_title("Stability regions |ζ| ≤ 1 (explicit: inside; BDF: outside)\n"
                      "dashed: A(α) sectors of BDF3–6")
    axes[1].set_title(f"Zoom: h λ along the runs (h = {study.data['period_s']:g} s), "
                      f"max |h λ| = {study.data['stiffness']['paper']['max_abs_h_lambda']:.2g}")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=7, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    return fig


def error_vs_step_figure(study: StiffnessStudy) -> Figure:
    """Error against the step: the verification orbit (exact solution) and the reconstruction problem."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    panels = (
        (axes[0], study.plots["verification"], "orbit verification problem (exact solution)"),
        (axes[1], study.plots["paper_accuracy"], "reconstruction of the occlusion (vs Radau, rtol 1e-13)"),
    )
    for ax, rows, title in panels:
        for scheme, row in rows.items():
            order = row["observed_order"]
            label = f"{scheme} ({order:.2f})" if order is not None else f"{scheme} (no fit)"
            ax.loglog(row["steps_s"], row["errors"], marker=_MARKERS.get(scheme, "."), color=_COLORS[scheme],
                      label=label)
        ax.set_xlabel("step h [s]")
        ax.set_ylabel("max(|ΔX|, |ΔY|, |Δz|/z)")
        ax.set_title(title)
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=7, ncol=2, title="scheme (observed order)", title_fontsize=7)
    axes[1].axhline(1e-11, color="k", lw=0.6, ls=":")
    axes[1].text(axes[1].get_xlim()[0], 1.3e-11, " fit floor", fontsize=7)
    fig.tight_layout()
    return fig


def _cost_figure(costs: dict[str, Any], errors: dict[str, Any], front: list[tuple[float, float]],
                 xlabel: str) -> Figure:
    """Error against a cost per scheme (fixed-step solid, references dashed), with the Pareto front."""
    fig, ax = plt.subplots(figsize=(8, 5.5))
    for scheme in FIXED_STEP_SCHEMES + REFERENCE_SCHEMES:
        if scheme not in costs:
            continue
        ls = "-" if scheme in FIXED_STEP_SCHEMES else "--"
        ax.loglog(costs[scheme], errors[scheme], ls, marker=_MARKERS.get(scheme, "."), color=_COLORS[scheme],
                  label=scheme)
    if front:
        ax.loglog([p[0] for p in front], [p[1] for p in front], color="k", lw=2, alpha=0.25, label="Pareto front")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("max(|ΔX|, |ΔY|, |Δz|/z)")
    ax.set_title("Cost and accuracy on the reconstruction problem\n(fixed-step: steps 0.2…0.0125 s; "
                 "references: rtol ladder)")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return fig


def _accuracy(study: StiffnessStudy) -> dict[str, Any]:
    return {**study.plots["paper_accuracy"], **study.plots["reference_accuracy"]}


def error_vs_time_figure(study: StiffnessStudy) -> Figure:
    """Error against wall-clock time (medians) on the reconstruction problem, with the Pareto front."""
    accuracy = _accuracy(study)
    schemes = [k for k in accuracy if k in study.timing]
    front = [(p["wall_s"], p["error"]) for p in study.timing.get("pareto_front", [])]
    return _cost_figure({k: study.timing[k]["wall_s"] for k in schemes}, {k: accuracy[k]["errors"] for k in schemes},
                        front, "wall-clock time [s] (median)")


def error_vs_evaluations_figure(study: StiffnessStudy) -> Figure:
    """Error against the evaluations of ``F`` and its Jacobian on the reconstruction problem, with the Pareto
    front by evaluations: the cost axis of :func:`error_vs_time_figure` without the machine's clock, so the
    figure is the same bytes on every machine (the report's)."""
    accuracy = _accuracy(study)
    front = sorted((accuracy[p["scheme"]]["evaluations"][p["index"]], accuracy[p["scheme"]]["errors"][p["index"]])
                   for p in study.data["accuracy"]["paper"].get("pareto_front_by_evaluations", []))
    return _cost_figure({k: r["evaluations"] for k, r in accuracy.items()}, {k: r["errors"] for k, r in accuracy.items()},
                        front, "evaluations of F and its Jacobian")


def stiffness_ratio_figure(study: StiffnessStudy) -> Figure:
    """Stiffness ratio, raw Lambert ratio and ``h ρ(∂F/∂ψ)`` over the run's reconstruction samples."""
    spec = study.plots["paper_spectrum"]
    t0, t1 = study.plots["occlusion"]
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    for ax in axes:
        ax.axvspan(t0, t1, color="0.9", label="occlusion window")
    axes[0].semilogy(spec.times, spec.stiffness_ratio, ".", ms=2, label="stiffness ratio (rates ≥ 1/window)")
    axes[0].semilogy(spec.times, spec.lambert_ratio, ".", ms=2, color="tab:red", alpha=0.5,
                     label="raw Lambert max|Re λ| / min|Re λ|")
    axes[0].set_ylabel("ratio")
    axes[0].legend(fontsize=7)
    axes[1].plot(spec.times, spec.period * spec.spectral_radius, ".", ms=2)
    axes[1].set_ylabel("h ρ(∂F/∂ψ)")
    axes[1].set_xlabel("t [s]")
    for ax in axes:
        ax.grid(True, which="both", lw=0.3)
    axes[0].set_title("Stiffness of (13) where the estimator reconstructs (paper run)")
    fig.tight_layout()
    return fig


def stiffness_figures(study: StiffnessStudy, *, reproducible: bool = False) -> dict[str, Figure]:
    """The four figures keyed by file stem; ``reproducible``: the cost against evaluations instead of wall-clock
    time (the report's choice: every byte of it is the same on every machine)."""
    cost = ({"stiffness_error_vs_evaluations": error_vs_evaluations_figure(study)} if reproducible
            else {"stiffness_error_vs_time": error_vs_time_figure(study)})
    return {
        "stiffness_regions": stability_regions_figure(study),
        "stiffness_error_vs_step": error_vs_step_figure(study),
        **cost,
        "stiffness_ratio": stiffness_ratio_figure(study),
    }
