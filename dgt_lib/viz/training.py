"""Figures and tables of notebook 03 (multi-task training).

Paper: Network Architecture, Multi-Task Learning and Baselines (DGT-Map(ST)).

The network's parts and shapes (:func:`parameter_table`, :func:`shape_trace`), the masked
loss's gradients per head (:func:`head_gradient_norms`), learning curves, multi-task
against single-task test errors (:func:`comparison_table`, :func:`own_head_predictions`),
predictions on chosen patches, and the width trade-off measured by
:func:`dgt_lib.learning.tradeoff.width_tradeoff` (its table and figure).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np

from dgt_lib.core.config import VEHICLES
from dgt_lib.viz.common import METHOD_COLORS, VEHICLE_COLORS

TRAINING_COLORS = {"multi-task": METHOD_COLORS["dgt"], "single-task": METHOD_COLORS["single-task"]}
"""Colours of the multi-task model and the single-task models (as in the experiments)."""


def parameter_table(model) -> str:
    """A Markdown table of a :class:`~dgt_lib.learning.model.DGTNet`'s trainable parameters per
    part: the RGB and height ResNet-18 branches, the FC layer after the concatenation,
    the vehicle heads, and the total (with each part's share)."""
    from dgt_lib.learning.model import count_parameters

    parts = {"RGB branch (ResNet-18)": model.rgb, "height branch (ResNet-18)": model.height,
             "FC + ReLU after the concatenation": model.fc,
             f"{len(model.vehicles)} vehicle heads (linear + sigmoid)": model.vehicle_heads}
    total = count_parameters(model)
    lines = ["| part | parameters | share |", "|---|---:|---:|"]
    for name, module in parts.items():
        n = count_parameters(module)
        lines.append(f"| {name} | {n:,} | {n / total:.1%} |")
    lines.append(f"| **total** | **{total:,}** | 100% |")
    return "\n".join(lines)


def shape_trace(model, x) -> list[tuple[str, tuple[int, ...]]]:
    """The tensor shapes through a DGTNet for patches ``x`` (B, 6, 22, 7), in the order
    they are computed: (stage, shape) for the input, each branch's input, stem
    convolution, max-pool, four ResNet stages and pooled embedding, the concatenation,
    the shared embedding z and the heads' output. Runs once in eval mode, no gradients."""
    import torch

    trace: list[tuple[str, tuple[int, ...]]] = [("input patches (R, G, B, H̄, σ_H, ‖∇H̄‖)",
                                                 tuple(x.shape))]
    steps = {"conv1": "conv 7×7 /2", "maxpool": "max-pool 3×3 /2", "layer1": "layer1",
             "layer2": "layer2 /2", "layer3": "layer3 /2", "layer4": "layer4 /2",
             "avgpool": "global average pool"}

    def after(name):
        return lambda module, args, out: trace.append((name, tuple(out.shape)))

    def before(name):
        return lambda module, args: trace.append((name, tuple(args[0].shape)))

    hooks = []
    for branch in ("rgb", "height"):
        net = getattr(model, branch)
        hooks.append(net.register_forward_pre_hook(before(f"{branch}: input channels")))
        hooks += [getattr(net, part).register_forward_hook(after(f"{branch}: {label}"))
                  for part, label in steps.items()]
    hooks.append(model.fc.register_forward_pre_hook(before("concatenation")))
    hooks.append(model.fc.register_forward_hook(after("shared embedding z (FC + ReLU)")))
    was_training = model.training
    model.eval()
    try:
        with torch.no_grad():
            out = model(x)
    finally:
        for hook in hooks:
            hook.remove()
        model.train(was_training)
    trace.append(("heads + sigmoid: L̂ per vehicle", tuple(out.shape)))
    return trace


def shape_table(trace: Sequence[tuple[str, tuple[int, ...]]]) -> str:
    """:func:`shape_trace` as a Markdown table (stage, shape)."""
    rows = [f"| {name} | {tuple(shape)} |" for name, shape in trace]
    return "\n".join(["| stage | shape |", "|---|---|", *rows])


def head_gradient_norms(model, x, labels, head) -> np.ndarray:
    """L2 norm of the gradient of :func:`~dgt_lib.learning.training.masked_loss` with respect
    to each
    vehicle head's parameters, for one batch: x (B, 6, 22, 7), labels (B,) and head (B,)
    int64 column of each sample's vehicle. Returns (n_heads,); heads of vehicles not in
    the batch get exactly 0. The model's gradients are cleared before and after."""
    import torch

    from dgt_lib.learning.training import masked_loss

    model.zero_grad(set_to_none=True)
    masked_loss(model(x), labels, head).backward()
    norms = []
    for h in model.vehicle_heads:
        grads = [p.grad for p in h.parameters() if p.grad is not None]
        norms.append(float(torch.sqrt(sum((g**2).sum() for g in grads))) if grads else 0.0)
    model.zero_grad(set_to_none=True)
    return np.array(norms)


def plot_learning_curves(histories: Mapping[str, Sequence[Mapping[str, float]]],
                         best_epochs: Mapping[str, int]):
    """Training and validation loss (mean masked squared error) per epoch, one panel per
    model (``histories[name]`` = ``TrainResult.history``); the kept (best validation)
    epoch ``best_epochs[name]`` is starred."""
    from matplotlib.ticker import MaxNLocator

    n = len(histories)
    fig, axes = plt.subplots(1, n, figsize=(3.4 * n, 3.2), squeeze=False,
                             constrained_layout=True)
    for ax, (name, history) in zip(axes[0], histories.items(), strict=True):
        epoch = [h["epoch"] for h in history]
        ax.plot(epoch, [h["train_loss"] for h in history], "o-", ms=3, label="train")
        ax.plot(epoch, [h["val_loss"] for h in history], "s-", ms=3, label="validation")
        best = next(h for h in history if h["epoch"] == best_epochs[name])
        ax.plot(best["epoch"], best["val_loss"], "*", ms=14, color="gold", mec="k",
                label=f"kept: epoch {best['epoch']}")
        ax.set_title(name)
        ax.set_xlabel("epoch")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.legend(fontsize=7)
    axes[0, 0].set_ylabel("masked MSE")
    return fig


METRIC_NAMES = {"mse": "MSE", "mae": "MAE", "spearman": "Spearman ρ"}


def comparison_table(metrics: Mapping[str, Mapping[str, Mapping[str, float]]],
                     n_train: Mapping[str, int]) -> str:
    """A Markdown table of test errors per vehicle and model.

    metrics: ``{model: {vehicle: {"n", "mse", "mae", "spearman"}}}`` (e.g. ``{"multi-task":
    result.metrics, "single-task": {...}}``); n_train: training patches per vehicle.
    Columns: the vehicle's training and test patches, then MSE, MAE and Spearman ρ of
    every model; with exactly two models a last column gives the second's MSE minus the
    first's (positive: the first is better). A missing value shows as "–".
    """
    models = list(metrics)

    def cell(model: str, vehicle: str, key: str) -> str:
        value = metrics[model].get(vehicle, {}).get(key, float("nan"))
        return "–" if not np.isfinite(value) else f"{value:.{2 if key == 'spearman' else 4}f}"

    head = ["vehicle", "train patches", "test patches"]
    head += [f"{METRIC_NAMES[k]} {m}" for k in METRIC_NAMES for m in models]
    if len(models) == 2:
        head.append(f"MSE {models[1]} − {models[0]}")
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for v in VEHICLES:
        n_test = next((int(metrics[m][v]["n"]) for m in models if v in metrics[m]), 0)
        row = [v, str(n_train.get(v, 0)), str(n_test)]
        row += [cell(m, v, k) for k in METRIC_NAMES for m in models]
        if len(models) == 2:
            a, b = (metrics[m].get(v, {}).get("mse", float("nan")) for m in models)
            row.append("–" if not np.isfinite(b - a) else f"{b - a:+.4f}")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def plot_metric_comparison(metrics: Mapping[str, Mapping[str, Mapping[str, float]]],
                           n_train: Mapping[str, int]):
    """Grouped bars of test MSE, MAE and Spearman ρ per vehicle (x, with its training
    patches), one bar per model (same arguments as :func:`comparison_table`)."""
    models = list(metrics)
    x = np.arange(len(VEHICLES))
    w = 0.8 / len(models)
    fig, axes = plt.subplots(1, len(METRIC_NAMES), figsize=(14, 3.6), constrained_layout=True)
    for ax, (key, label) in zip(axes, METRIC_NAMES.items(), strict=True):
        for k, m in enumerate(models):
            values = np.array([metrics[m].get(v, {}).get(key, np.nan) for v in VEHICLES])
            pos = x + (k - (len(models) - 1) / 2) * w
            ax.bar(pos, np.nan_to_num(values), w, label=m,
                   color=TRAINING_COLORS.get(m, f"C{k}"))
            for p, value in zip(pos, values, strict=True):
                if not np.isfinite(value):
                    ax.text(p, 0, "n/a", ha="center", va="bottom", fontsize=7)
        ax.set_xticks(x, [f"{v}\n({n_train.get(v, 0)} train)" for v in VEHICLES], fontsize=8)
        ax.set_title(f"test {label}" + (" (higher is better)" if key == "spearman"
                                        else " (lower is better)"))
        ax.axhline(0, color="k", lw=0.5)
    axes[0].legend()
    return fig


def own_head_predictions(multitask, single: Mapping[str, object], part
                         ) -> dict[str, np.ndarray]:
    """Each sample's prediction by its own vehicle's head: ``{"multi-task": (N,),
    "single-task": (N,)}`` for the samples of ``part`` (a PatchDataset). ``single`` maps a
    vehicle to its single-task model; samples of a vehicle without one get NaN."""
    from dgt_lib.learning.training import predict

    columns = np.array([multitask.head_index(v) for v in range(len(VEHICLES))])
    multi = predict(multitask, part.patches)[np.arange(len(part)), columns[part.vehicle]]
    solo = np.full(len(part), np.nan, dtype=np.float32)
    for name, model in single.items():
        idx = np.flatnonzero(part.vehicle == VEHICLES.index(name))
        if len(idx):
            solo[idx] = predict(model, part.patches[idx])[:, model.head_index(name)]
    return {"multi-task": multi, "single-task": solo}


def plot_predicted_vs_true(predictions: Mapping[str, np.ndarray], labels: np.ndarray,
                           vehicle: np.ndarray):
    """Predicted against true L, one panel per vehicle, one colour per model
    (``predictions[model]`` (N,), e.g. from :func:`own_head_predictions`; labels (N,),
    vehicle (N,) head indices). The diagonal is a perfect prediction."""
    fig, axes = plt.subplots(1, len(VEHICLES), figsize=(3.6 * len(VEHICLES), 3.8),
                             sharex=True, sharey=True, constrained_layout=True)
    for v, (ax, name) in enumerate(zip(axes, VEHICLES, strict=True)):
        sel = vehicle == v
        ax.plot([0, 1], [0, 1], color="0.6", lw=1)
        for k, (model, pred) in enumerate(predictions.items()):
            ok = sel & np.isfinite(pred)
            if ok.any():
                mse = np.mean((pred[ok] - labels[ok]) ** 2)
                ax.scatter(labels[ok], pred[ok], s=10, alpha=0.5, linewidths=0,
                           color=TRAINING_COLORS.get(model, f"C{k}"),
                           label=f"{model} (MSE {mse:.3f})")
        ax.set_title(f"{name}: {int(sel.sum())} test patches")
        ax.set_xlabel("true L")
        ax.set_xlim(-0.03, 1.03)
        ax.set_ylim(-0.03, 1.03)
        ax.set_aspect("equal")
        if ax.has_data():
            ax.legend(fontsize=7, loc="upper left")
    axes[0].set_ylabel("predicted L̂")
    return fig


def plot_predicted_patches(patches: np.ndarray, observed: np.ndarray, names: Sequence[str],
                           predictions: np.ndarray):
    """Chosen patches with every vehicle's predicted L̂: per patch a column of its RGB,
    its H̄ relative to the height under the vehicle [m] (forward = up) and one bar per
    vehicle. patches (n, 6, 22, 7), observed (n, 22, 7), names (n,), predictions (n, 4)
    in :data:`VEHICLES` order. Each height panel has its own colour scale (± its largest
    |H̄ − centre|, at least 0.1 m), so a 0.7 m ridge shows next to a 9 m tree."""
    from dgt_lib.perception.bev import HEIGHT

    n = len(names)
    fig, axes = plt.subplots(3, n, figsize=(2.6 * n, 8.2), squeeze=False,
                             gridspec_kw={"height_ratios": [3, 3, 2]}, constrained_layout=True)
    cm = plt.get_cmap("coolwarm").copy()
    cm.set_bad("0.8")
    centre = (slice(10, 12), 3)  # the vehicle sits between rows 10 and 11, column 3
    rel = []
    for p, obs in zip(patches, observed, strict=True):
        h = p[HEIGHT].astype(np.float64)
        ref = h[centre][obs[centre]].mean() if obs[centre].any() else h[obs].mean()
        rel.append(np.ma.masked_array(h - ref, mask=~obs))
    for k in range(n):
        rgb = np.clip(np.moveaxis(patches[k, :3].astype(np.float32), 0, -1), 0, 1)
        axes[0, k].imshow(np.where(observed[k][..., None], rgb, 0.8))
        axes[0, k].set_title(names[k], fontsize=9, wrap=True)
        lim = max(float(np.abs(rel[k]).max()), 0.1)
        im = axes[1, k].imshow(rel[k], cmap=cm, vmin=-lim, vmax=lim)
        fig.colorbar(im, ax=axes[1, k], orientation="horizontal", shrink=0.8, pad=0.02,
                     label="H̄ − centre [m]")
        for ax in axes[:2, k]:
            ax.set_xticks([])
            ax.set_yticks([])
        bars = axes[2, k].bar(range(len(VEHICLES)), predictions[k],
                              color=[VEHICLE_COLORS[v] for v in VEHICLES])
        axes[2, k].bar_label(bars, fmt="%.2f", fontsize=7)
        axes[2, k].set_ylim(0, 1.15)
        axes[2, k].set_xticks(range(len(VEHICLES)), VEHICLES, rotation=60, fontsize=7)
    axes[0, 0].set_ylabel("RGB")
    axes[1, 0].set_ylabel("H̄ − centre")
    axes[2, 0].set_ylabel("predicted L̂")
    fig.suptitle("multi-task predictions; the vehicle drives up the page from the centre")
    return fig


def tradeoff_table(rows: Sequence[Mapping[str, float]]) -> str:
    """:func:`~dgt_lib.learning.tradeoff.width_tradeoff` rows as a Markdown table."""
    lines = ["| width | parameters | test MSE | inference [patches/s] | training [s] |",
             "|---:|---:|---:|---:|---:|"]
    lines += [f"| {r['width']} | {r['parameters'] / 1e6:.2f} M | {r['test_mse']:.4f} | "
              f"{r['patches_per_s']:,.0f} | {r['train_s']:.1f} |" for r in rows]
    return "\n".join(lines)


def plot_width_tradeoff(rows: Sequence[Mapping[str, float]], paper_width: int = 64):
    """Test MSE against inference speed, one point per network width (labelled with its
    parameter count); ``paper_width`` (the paper's ResNet-18) is drawn as a star."""
    from matplotlib.ticker import StrMethodFormatter

    fig, ax = plt.subplots(figsize=(6.5, 4), constrained_layout=True)
    for k, r in enumerate(rows):  # labels alternate above and below: neighbours may be close
        paper = r["width"] == paper_width
        ax.scatter(r["patches_per_s"], r["test_mse"], s=160 if paper else 50,
                   marker="*" if paper else "o", color="tab:blue", zorder=2)
        ax.annotate(f"width {r['width']}{' (paper)' if paper else ''}\n"
                    f"{r['parameters'] / 1e6:.2f} M", (r["patches_per_s"], r["test_mse"]),
                    textcoords="offset points", xytext=(6, 6 if k % 2 == 0 else -22),
                    fontsize=8)
    ax.set_xlim(0, 1.3 * max(r["patches_per_s"] for r in rows))
    ax.xaxis.set_major_formatter(StrMethodFormatter("{x:,.0f}"))
    ax.set_xlabel("inference speed [patches/s] (right is faster)")
    ax.set_ylabel("test MSE, all vehicles (lower is better)")
    ax.set_title("network width: accuracy against speed")
    ax.margins(y=0.25)
    return fig


def plot_head_init(predictions: Mapping[str, np.ndarray], labels: np.ndarray,
                   vehicle: str = "jeep", bins: int = 40):
    """Histograms of one head's test predictions L̂ per head initialisation (e.g.
    ``{"default": …, "prior": …}``) over the true labels L, each titled with
    std(L̂) / std(L) — below 0.1 the head has collapsed to a constant
    (:func:`dgt_lib.learning.training.collapsed_heads`)."""
    labels = np.asarray(labels, dtype=np.float64)
    fig, axes = plt.subplots(1, len(predictions), figsize=(5.5 * len(predictions), 3.6),
                             squeeze=False, sharey=True)
    edges = np.linspace(0.0, 1.0, bins + 1)
    for ax, (name, pred) in zip(axes[0], predictions.items(), strict=True):
        pred = np.asarray(pred, dtype=np.float64)
        ratio = pred.std() / max(labels.std(), 1e-12)
        ax.hist(labels, edges, color="0.75", label="true L (test)")
        ax.hist(pred, edges, histtype="step", lw=2, color=VEHICLE_COLORS.get(vehicle, "k"),
                label="predicted L̂")
        ax.set_yscale("log")
        ax.set_xlabel("locomotion L")
        state = "collapsed" if ratio < 0.1 else "learning"
        ax.set_title(f"head init '{name}': std(L̂)/std(L) = {ratio:.2f} ({state})")
        ax.legend(fontsize=8)
    axes[0][0].set_ylabel(f"{vehicle} test patches")
    fig.tight_layout()
    return fig
