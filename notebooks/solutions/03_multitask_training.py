"""Reference solutions of notebook 03's exercises (paper: Multi-Task Learning)."""

from __future__ import annotations


def my_masked_loss(pred, labels, head):
    """Mean over the batch of (pred[i, head[i]] − labels[i])²: each patch P counts only
    through the head of the vehicle that collected it, 𝓛(P, v) = ‖L̂_v(P) − L_v(t_P)‖²."""
    own = pred.gather(1, head[:, None]).squeeze(1)  # (B,) L̂_v(P)
    return ((own - labels) ** 2).mean()
