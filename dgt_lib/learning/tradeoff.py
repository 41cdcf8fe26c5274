"""How fast a DGTNet infers, and what its width trades between accuracy and speed.

Paper: Network Architecture (ResNet-18 branches) and the limitation Directional
Inference Cost: a costmap evaluates the network on every cell and heading, so its
speed in patches per second matters. :func:`width_tradeoff` trains the multi-task
model at several widths and measures each one's test error and :func:`inference_rate`;
notebook 03 shows the result with :func:`dgt_lib.viz.training.tradeoff_table` and
:func:`dgt_lib.viz.training.plot_width_tradeoff`.

Torch and the training code are imported when a function runs, so that importing
:mod:`dgt_lib.viz` (which re-exports both functions for the notebooks) stays light.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def inference_rate(model, patches: np.ndarray, *, repeats: int = 3,
                   batch_size: int = 1024) -> float:
    """Inference speed in patches per second: the best of ``repeats`` timed runs of
    :func:`~dgt_lib.learning.training.predict` over ``patches`` (N, 6, 22, 7), after one warm-up
    batch. Measured on the model's device with torch's current thread count."""
    import time

    from dgt_lib.learning.training import predict

    if repeats < 1 or len(patches) == 0:
        raise ValueError(f"need repeats ≥ 1 and patches, got {repeats} and {len(patches)}")
    predict(model, patches[:batch_size], batch_size)
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        predict(model, patches, batch_size)
        best = min(best, time.perf_counter() - t0)
    return len(patches) / max(best, 1e-9)


def width_tradeoff(dataset, cfg, widths: Sequence[int], *, epochs: int, seed: int = 0,
                   n_patches: int = 4096, progress: bool = True) -> list[dict[str, float]]:
    """Train the multi-task model at each ``width`` for ``epochs`` (else as ``cfg``, a
    TrainConfig) and measure it: one dict per width with ``width``, ``parameters``,
    ``test_mse`` (masked MSE over every vehicle's test patches, each by its own head),
    ``patches_per_s`` (:func:`inference_rate` on ``n_patches`` test patches, repeated to
    that many) and ``train_s`` (seconds of training)."""
    from dataclasses import replace

    from tqdm.auto import tqdm

    from dgt_lib.learning.model import count_parameters
    from dgt_lib.learning.run import train_model

    test = dataset.part("test")
    if len(test) == 0:
        raise ValueError("the dataset has no test patches to score the widths on")
    timing = np.resize(test.patches, (n_patches, *test.patches.shape[1:]))
    rows = []
    for width in tqdm(widths, desc="widths", disable=not progress):
        run = replace(cfg, width=int(width), epochs=int(epochs), patience=None)
        result = train_model(dataset, run, seed=seed, progress=False)
        scores = result.metrics.values()
        n = sum(m["n"] for m in scores)
        rows.append({"width": int(width), "parameters": count_parameters(result.model),
                     "test_mse": sum(m["n"] * m["mse"] for m in scores) / n,
                     "patches_per_s": inference_rate(result.model, timing, repeats=5),
                     "train_s": sum(h["seconds"] for h in result.history)})
    return rows
