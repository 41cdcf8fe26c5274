"""Figures of MPPI path tracking (notebooks 06 and 11; paper: Controller Integration):
sampled rollouts over the occupancy map coloured by their weight, the critics' terms, the
weights against the temperature λ, a warm-start trace, and a drive's commands over time.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from dgt_lib.core.geometry import GridSpec
from dgt_lib.navigation.control.mppi import SampledRollouts, mppi_weights


def effective_samples(weights: np.ndarray) -> float:
    """Kish's effective sample size 1 / Σ w_b² of normalised weights: how many samples
    the average really rests on (B for equal weights, 1 when one takes all)."""
    w = np.asarray(weights, np.float64)
    return float(1.0 / np.sum(w * w))


def plot_rollouts(ax, rollouts: SampledRollouts, temperature: float, path: np.ndarray,
                  occupancy: np.ndarray | None = None, grid: GridSpec | None = None,
                  optimal: np.ndarray | None = None, n_show: int = 150):
    """The sampled rollouts (x, y ``(T, B)``) over the occupancy map, the ``n_show``
    heaviest coloured by their weight w_b = exp(−(S_b − min S)/λ)/η, the reference
    ``path`` ``(N, ≥2)`` and the ``optimal`` trajectory ``(T, ≥2)``."""
    if occupancy is not None:
        x0, y0 = grid.origin_xy
        ax.imshow(occupancy > 0, origin="lower", cmap="Greys", vmin=0, vmax=1.5,
                  extent=(x0, x0 + grid.width * grid.resolution,
                          y0, y0 + grid.height * grid.resolution))
    weights = mppi_weights(rollouts.cost, temperature)
    order = np.argsort(weights)[-n_show:]  # the heaviest last, drawn on top
    cmap = plt.get_cmap("viridis")
    top = weights[order].max()
    for b in order:
        ax.plot(rollouts.x[:, b], rollouts.y[:, b], color=cmap(weights[b] / top), lw=0.6,
                alpha=0.8)
    ax.plot(path[:, 0], path[:, 1], "k--", lw=1.2, label="reference path")
    if optimal is not None:
        ax.plot(optimal[:, 0], optimal[:, 1], color="tab:red", lw=2.2, label="optimal u*")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{rollouts.x.shape[1]} sampled rollouts, colour = weight (λ = {temperature})")
    ax.legend(loc="upper left", fontsize=8)
    return ax.figure


def plot_critic_terms(ax, rollouts: SampledRollouts, collision_weight: float | None = None):
    """Each critic's term, stacked, over the samples sorted by total cost S: which term
    separates the cheap samples from the dear ones. With ``collision_weight`` the samples
    that collide (S ≥ it) are left out and counted in the title (their cost dwarfs the
    rest)."""
    order = np.argsort(rollouts.cost)
    if collision_weight is not None:
        hit = int((rollouts.cost >= collision_weight).sum())
        order = order[:len(order) - hit]
        ax.set_title(f"{hit} of {len(rollouts.cost)} samples collide (S ≥ {collision_weight:g}),"
                     " not shown")
    bottom = np.zeros(len(order))
    for name, term in rollouts.terms.items():
        ax.fill_between(np.arange(len(order)), bottom, bottom + term[order], label=name,
                        step="mid", alpha=0.8)
        bottom = bottom + term[order]
    ax.set_xlabel("sample, cheapest first")
    ax.set_ylabel("cost S (stacked critics)")
    ax.legend(fontsize=8)
    return ax.figure


def plot_weights(ax, cost: np.ndarray, temperatures=(0.03, 0.3, 3.0)):
    """The weights of one call's samples, sorted, for several λ, with each λ's effective
    number of samples (:func:`effective_samples`)."""
    for lam in temperatures:
        w = np.sort(mppi_weights(np.asarray(cost), lam))[::-1]
        ax.semilogy(np.arange(1, len(w) + 1), np.maximum(w, 1e-12),
                    label=f"λ = {lam}: {effective_samples(w):.0f} effective samples")
    ax.set_xlabel("sample rank")
    ax.set_ylabel("weight w_b")
    ax.set_ylim(1e-8, 1.5)
    ax.legend(fontsize=8)
    return ax.figure


def plot_warm_start_trace(ax, trace: dict[str, np.ndarray], model_dt_s: float):
    """A :func:`~dgt_lib.navigation.control.mppi.warm_start_trace`: per call, the command
    sent, the warm start's second step against the weighted one, and the plan's mean."""
    t = model_dt_s * np.arange(len(trace["command"]))
    ax.plot(t, trace["plan_mean"], color="tab:gray", label="plan's mean speed (2.8 s)")
    ax.plot(t, trace["warm_v1"], "--", color="tab:orange", label="warm start, step 1")
    ax.plot(t, trace["plan_v1"], color="tab:orange", label="weighted plan, step 1")
    ax.plot(t, trace["command"], color="tab:blue", lw=2, label="command sent (step 0)")
    ax.set_xlabel("call × model_dt [s]")
    ax.set_ylabel("speed [m/s]")
    ax.legend(fontsize=8)
    return ax.figure


def plot_drive(axes, t: np.ndarray, xy: np.ndarray, path: np.ndarray, speed: np.ndarray,
               command: np.ndarray, steer: np.ndarray | None = None, label: str = ""):
    """A drive: the track over the path (``axes[0]``), and speed against the command
    (``axes[1]``, with the steering in [−1, 1] when given)."""
    axes[0].plot(path[:, 0], path[:, 1], "k--", lw=1)
    axes[0].plot(xy[:, 0], xy[:, 1], lw=1.6, label=label or None)
    axes[0].set_aspect("equal")
    axes[0].set_xlabel("x [m]")
    axes[0].set_ylabel("y [m]")
    line, = axes[1].plot(t, speed, lw=1.6, label=f"speed {label}".strip())
    axes[1].plot(t, command, "--", color=line.get_color(), lw=1,
                 label=f"command {label}".strip())
    if steer is not None:
        axes[1].plot(t, steer, ":", color="tab:gray", lw=1, label="steer / lock")
    axes[1].set_xlabel("t [s]")
    axes[1].set_ylabel("[m/s]")
    axes[1].legend(fontsize=8)
    return axes[0].figure
