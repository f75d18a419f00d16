"""Figures of the stability analysis (``visnav analyse``): Bode, Nyquist, margins and eigenvalues against the gains.

Rendering code: it takes the JSON-ready dictionary of
:meth:`visnav.studies.loop_analysis.Analysis.as_dict` (so a saved ``analysis.json`` can be
re-plotted) and returns matplotlib figures (Agg backend, nothing shown); the
caller decides where they are written.
"""

from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

__all__ = ["bode_figure", "nyquist_figure", "margins_vs_gains_figure", "eigenvalues_vs_gains_figure",
           "analysis_figures"]


def _array(values: list[Any]) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def bode_figure(analysis: dict[str, Any]) -> Figure:
    """Bode magnitude and phase of every loop, continuous (solid) and sampled with ZOH + delay (dashed)."""
    fig, (mag, phase) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    names = [n for n in analysis["frequency_responses"] if n not in ("vs:e_Vz", "vs:e_Wx")]  # identical to e_Vy
    for i, name in enumerate(names):
        colour = colours[i % len(colours)]
        for kind, style in (("continuous", "-"), ("sampled", "--")):
            data = analysis["frequency_responses"][name][kind]
            w = _array(data["omega"])
            mag.semilogx(w, _array(data["magnitude_db"]), style, color=colour, lw=1.1,
                         label=f"{name} ({kind})")
            phase.semilogx(w, _array(data["phase_deg"]), style, color=colour, lw=1.1)
    mag.axhline(0.0, color="0.5", lw=0.7)
    phase.axhline(-180.0, color="0.5", lw=0.7)
    period = analysis["sampling_period_s"]
    for ax in (mag, phase):
        ax.axvline(np.pi / period, color="0.7", lw=0.7, ls=":")
        ax.grid(True, which="both", alpha=0.3)
    mag.set_ylabel("|L| [dB]")
    phase.set_ylabel("arg L [deg]")
    phase.set_xlabel("ω [rad/s]  (dotted: Nyquist frequency π/T)")
    mag.legend(fontsize=7, ncol=2)
    mag.set_title("Loop transfers: continuous vs sampled (ZOH + one sample of delay)")
    fig.tight_layout()
    return fig


def nyquist_figure(analysis: dict[str, Any]) -> Figure:
    """Nyquist curves (positive frequencies) near −1, continuous and sampled."""
    fig, ax = plt.subplots(figsize=(6, 6))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    names = [n for n in analysis["frequency_responses"] if n not in ("vs:e_Vz", "vs:e_Wx")]
    for i, name in enumerate(names):
        colour = colours[i % len(colours)]
        for kind, style in (("continuous", "-"), ("sampled", "--")):
            data = analysis["frequency_responses"][name][kind]
            ax.plot(_array(data["nyquist_real"]), _array(data["nyquist_imag"]), style, color=colour, lw=1.1,
                    label=f"{name} ({kind})")
    ax.plot([-1.0], [0.0], "r+", ms=12, mew=2)
    theta = np.linspace(0.0, 2.0 * np.pi, 200)
    ax.plot(np.cos(theta), np.sin(theta), color="0.7", lw=0.7, ls=":")
    ax.set_xlim(-3.0, 1.5)
    ax.set_ylim(-3.0, 1.5)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("Re L")
    ax.set_ylabel("Im L")
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title("Nyquist (ω > 0), critical point −1")
    fig.tight_layout()
    return fig


def margins_vs_gains_figure(analysis: dict[str, Any]) -> Figure:
    """Gain and phase margins against k, λ_gc and λ_VS, continuous and sampled; sampled stability limits."""
    curves = analysis["margins_vs_gains"]
    fig, axes = plt.subplots(2, len(curves), figsize=(4 * len(curves), 6), squeeze=False)
    for j, (key, curve) in enumerate(curves.items()):
        gain_name = next(k for k in curve if k in ("k", "lambda_gc", "lambda_vs"))
        g = np.array(curve[gain_name], dtype=float)
        for kind, style in (("continuous", "-o"), ("sampled", "--s")):
            axes[0, j].semilogx(g, _array(curve[kind]["gain_margin_db"]), style, ms=3, label=kind)
            axes[1, j].semilogx(g, _array(curve[kind]["phase_margin_deg"]), style, ms=3, label=kind)
        limit = curve["sampled"].get("stability_limit")
        for ax in axes[:, j]:
            if limit is not None:
                ax.axvline(limit, color="tab:red", lw=0.8, ls=":", label=f"sampled limit {limit:.4g}")
            ax.grid(True, which="both", alpha=0.3)
        axes[0, j].axhline(0.0, color="0.5", lw=0.7)
        axes[0, j].set_title(key.replace("_", " "))
        axes[1, j].set_xlabel(gain_name)
        axes[0, j].legend(fontsize=7)
    axes[0, 0].set_ylabel("gain margin [dB] (gaps: infinite)")
    axes[1, 0].set_ylabel("phase margin [deg]")
    fig.tight_layout()
    return fig


def eigenvalues_vs_gains_figure(analysis: dict[str, Any]) -> Figure:
    """Closed-loop eigenvalues of path following against k and v_coll, and of the goal loops against λ."""
    pf = analysis["path_following"]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for ax, key, name in ((axes[0], "eigenvalues_vs_k", "k"), (axes[1], "eigenvalues_vs_v_coll", "v_coll_mps")):
        curve = pf[key]
        x = np.array(curve[name], dtype=float)
        eig = np.array(curve["eigenvalues"], dtype=float)  # (points, 2, [re, im])
        for i in range(eig.shape[1]):
            ax.plot(x, eig[:, i, 0], "-o", ms=3, label=f"Re λ{i + 1}")
        if name == "k":
            ax.set_xscale("log")
        ax.set_xlabel(name)
        ax.set_ylabel("Re λ [1/s]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title(f"path following vs {name}")
    lam = analysis["eigenvalues_vs_lambda"]
    x = np.array(lam["lambda"], dtype=float)
    vs = np.array(lam["vs_task_eigenvalues"], dtype=float)[:, 0, 0]
    pan = np.array(lam["pan_eigenvalues"], dtype=float)[:, 0, 0]
    axes[2].loglog(x, -vs, "-o", ms=3, label="−λ(e_VS task)")
    axes[2].loglog(x, -pan, "--s", ms=3, label="−λ(pan task)")
    axes[2].set_xlabel("λ_VS, λ_gc [1/s]")
    axes[2].set_ylabel("−Re λ [1/s]")
    axes[2].grid(True, which="both", alpha=0.3)
    axes[2].legend(fontsize=7)
    axes[2].set_title("goal loops vs gain")
    fig.tight_layout()
    return fig


def analysis_figures(analysis: dict[str, Any]) -> dict[str, Figure]:
    """All the analysis figures, keyed by a file stem."""
    return {
        "analysis_bode": bode_figure(analysis),
        "analysis_nyquist": nyquist_figure(analysis),
        "analysis_margins_vs_gains": margins_vs_gains_figure(analysis),
        "analysis_eigenvalues_vs_gains": eigenvalues_vs_gains_figure(analysis),
    }
