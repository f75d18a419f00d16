"""Figures reproducing the paper's figures 4–7 from a simulation result.

Rendering code: it builds matplotlib figures (Agg backend, nothing shown) and
returns them; the CLI decides where they are written.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402

from hybrid import HybridAutomaton  # noqa: E402

from visnav.simulation import SimulationResult  # noqa: E402

__all__ = [
    "trajectory_figure",
    "risk_figure",
    "reconstruction_figure",
    "controls_figure",
    "paper_figures",
    "mode_graph_figure",
]


def _shade_modes(ax: plt.Axes, result: SimulationResult) -> None:
    """Grey background while at least one feature is hidden."""
    t = result.trace.times
    hidden = result.trace.record("n_hidden") > 0
    if hidden.any():
        ax.fill_between(t, 0, 1, where=hidden, transform=ax.get_xaxis_transform(), color="0.9", step="mid",
                        label="feature(s) hidden")


def trajectory_figure(result: SimulationResult) -> Figure:
    """Figure 4: the robot path with the obstacles and their envelopes ξ−, ξ0, ξ+."""
    s = result.scenario
    fig, ax = plt.subplots(figsize=(8, 5))
    env = s.envelopes
    for obstacle in s.obstacles:
        cx, cy = obstacle.center_m
        tall = obstacle.occludes(s.robot.camera_height_m)
        ax.add_patch(Circle((cx, cy), obstacle.radius_m, color="0.3" if tall else "0.6", zorder=2))
        for d, style in ((env.d_minus_m, ":"), (env.d_zero_m, "--"), (env.d_plus_m, "-.")):
            ax.add_patch(Circle((cx, cy), obstacle.radius_m + d, fill=False, ls=style, lw=0.8, color="tab:red"))
        ax.annotate(f"{obstacle.name} ({'tall' if tall else 'low'})", (cx, cy + obstacle.radius_m + env.d_plus_m),
                    ha="center", va="bottom", fontsize=8)
    xy = result.trace.states[:, :2]
    mu_coll = result.trace.record("mu_coll")
    ax.plot(xy[:, 0], xy[:, 1], color="tab:blue", lw=1.2, label="robot M")
    avoid = mu_coll >= 1.0
    ax.plot(np.where(avoid, xy[:, 0], np.nan), np.where(avoid, xy[:, 1], np.nan), color="tab:orange", lw=2.0,
            label=r"$\mu_{coll}=1$")
    hidden = result.trace.record("n_hidden") > 0
    ax.plot(np.where(hidden, xy[:, 0], np.nan), np.where(hidden, xy[:, 1], np.nan), color="k", lw=0.8, ls="--",
            label="feature(s) hidden")
    theta = result.trace.states[:, 2]
    step = max(1, len(theta) // 25)
    ax.quiver(xy[::step, 0], xy[::step, 1], np.cos(theta[::step]), np.sin(theta[::step]), width=0.003,
              scale=30, color="tab:blue")
    target = np.array(s.target.points_m)
    ax.plot(target[:, 0], target[:, 1], "s", color="tab:green", label="target")
    ax.plot(s.goal.x_m, s.goal.y_m, "x", color="tab:green", label="goal M*")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"Robot trajectory ({s.name}) — paper fig. 4")
    ax.legend(fontsize=7, loc="best")
    ax.grid(True, lw=0.3)
    fig.tight_layout()
    return fig


def risk_figure(result: SimulationResult) -> Figure:
    """Figure 5: the risk parameters µ_coll and µ_occ over time."""
    t = result.trace.times
    fig, ax = plt.subplots(figsize=(8, 3.2))
    _shade_modes(ax, result)
    ax.plot(t, result.trace.record("mu_coll"), label=r"$\mu_{coll}$")
    ax.plot(t, result.trace.record("mu_occ"), label=r"$\mu_{occ}$")
    ax.set_ylim(-0.05, 1.05)
    ax.set_xlabel("t [s]")
    ax.set_title("Risk parameters — paper fig. 5")
    ax.legend(fontsize=8)
    ax.grid(True, lw=0.3)
    fig.tight_layout()
    return fig


def reconstruction_figure(result: SimulationResult) -> Figure:
    """Figure 6: ‖s − s̃‖ [px] and ‖z − z̃‖ [mm] over time."""
    s = result.scenario
    trace = result.trace
    n = len(s.target.points_m)
    f = s.camera.focal_px
    s_true = np.stack([trace.record(f"{c}{i}") for i in range(n) for c in ("X", "Y")], axis=1)
    s_est = np.stack([trace.record(f"{c}{i}_est") for i in range(n) for c in ("X", "Y")], axis=1)
    z_true = np.stack([trace.record(f"z{i}") for i in range(n)], axis=1)
    z_est = np.stack([trace.record(f"z{i}_est") for i in range(n)], axis=1)
    fig, axes = plt.subplots(2, 1, figsize=(8, 4.5), sharex=True)
    for ax, values, label in (
        (axes[0], f * np.linalg.norm(s_true - s_est, axis=1), r"$\|s-\tilde s\|$ [px]"),
        (axes[1], 1000 * np.linalg.norm(z_true - z_est, axis=1), r"$\|z-\tilde z\|$ [mm]"),
    ):
        _shade_modes(ax, result)
        ax.plot(trace.times, values)
        ax.set_ylabel(label)
        ax.grid(True, lw=0.3)
    axes[1].set_xlabel("t [s]")
    axes[0].set_title("Reconstruction errors — paper fig. 6 (grey: feature(s) hidden)")
    fig.tight_layout()
    return fig


def controls_figure(result: SimulationResult) -> Figure:
    """Figure 7: the inputs v, ω, ϖ with the stated actuator limits."""
    t = result.trace.times
    limits = result.scenario.limits
    fig, axes = plt.subplots(3, 1, figsize=(8, 5.5), sharex=True)
    for ax, name, label, lim in (
        (axes[0], "v_mps", "v [m/s]", limits.v_max_mps),
        (axes[1], "omega_radps", r"$\omega$ [rad/s]", limits.omega_max_radps),
        (axes[2], "pan_rate_radps", r"$\varpi$ [rad/s]", limits.pan_rate_max_radps),
    ):
        _shade_modes(ax, result)
        ax.step(t, result.trace.input(name), where="post")
        for sign in (-1, 1):
            ax.axhline(sign * lim, color="tab:red", lw=0.6, ls="--")
        ax.set_ylabel(label)
        ax.grid(True, lw=0.3)
    axes[2].set_xlabel("t [s]")
    axes[0].set_title("Control inputs (zero-order hold; dashed: actuator limits) — paper fig. 7")
    fig.tight_layout()
    return fig


def paper_figures(result: SimulationResult) -> dict[str, Figure]:
    """All four figures keyed by file stem."""
    return {
        "fig4_trajectory": trajectory_figure(result),
        "fig5_risk": risk_figure(result),
        "fig6_reconstruction": reconstruction_figure(result),
        "fig7_controls": controls_figure(result),
    }


def mode_graph_figure(automaton: HybridAutomaton) -> Figure:
    """The supervisor's product mode graph: collision phases as columns, occlusion phases as rows.

    Edges of the collision component are drawn in blue, those of the occlusion
    component in orange; each product transition is one arrow.
    """
    from hybrid import mode_graph

    from visnav.supervisor import COLLISION_PHASES, OCCLUSION_PHASES, split_mode

    graph = mode_graph(automaton)
    pos = {}
    for name in graph.nodes:
        collision, occlusion = split_mode(name)
        pos[name] = (COLLISION_PHASES.index(collision) * 2.2, -OCCLUSION_PHASES.index(occlusion) * 1.6)
    fig, ax = plt.subplots(figsize=(14, 6))
    for source, target, key, data in graph.edges(keys=True, data=True):
        (x0, y0), (x1, y1) = pos[source], pos[target]
        collision_edge = split_mode(source)[0] != split_mode(target)[0]
        ax.annotate(
            "",
            xy=(x1, y1),
            xytext=(x0, y0),
            arrowprops=dict(
                arrowstyle="-|>",
                color="tab:blue" if collision_edge else "tab:orange",
                lw=0.9,
                shrinkA=22,
                shrinkB=22,
                connectionstyle="arc3,rad=0.18",
            ),
        )
    for name, (x, y) in pos.items():
        collision, occlusion = split_mode(name)
        initial = name == automaton.initial_mode
        ax.text(x, y, f"{collision}\n{occlusion}", ha="center", va="center", fontsize=8,
                bbox=dict(boxstyle="round", fc="lightyellow" if initial else "white", ec="0.3"))
    ax.plot([], [], color="tab:blue", label="collision component (AVOID/LEAVE)")
    ax.plot([], [], color="tab:orange", label="occlusion component (OCCLU)")
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8)
    ax.set_xlim(-1.2, 2.2 * (len(COLLISION_PHASES) - 1) + 1.2)
    ax.set_ylim(-1.6 * (len(OCCLUSION_PHASES) - 1) - 0.8, 0.8)
    ax.axis("off")
    ax.set_title(f"{automaton.name}: {len(graph.nodes)} modes, {len(graph.edges)} transitions "
                 "(initial mode highlighted)")
    fig.tight_layout()
    return fig
