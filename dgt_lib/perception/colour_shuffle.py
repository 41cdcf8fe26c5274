"""Colours independent of the geometry: the BEV map's colour layer cut into square tiles
and the tiles permuted (the input attribution study; paper: Limitations → "The present
experiments do not isolate the contribution of RGB").

In the kit's worlds colour follows the terrain (a ridge's sharp crest is painted bare rock,
its smoothed crossing grass), so a network may learn "rock colour = costly" instead of the
relief. After the shuffle every cell's colour comes from a random other tile: the colours'
statistics and their texture within a tile stay, their place relative to slopes and crests
is gone. Geometry (H̄, σ_H, ‖∇H̄‖) and the observed mask are untouched.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dgt_lib.perception.bev import B, BEVMap, R

SHUFFLE_TILE_CELLS = 16
"""Side of a shuffled tile [cells] (6.4 m at 0.4 m: wider than a patch's 2.8 m, shorter than
its 8.8 m, so a patch mixes one to three tiles from unrelated places)."""


def shuffled_colours(bev: BEVMap, seed: int, tile_cells: int = SHUFFLE_TILE_CELLS) -> BEVMap:
    """``bev`` with its R, G, B channels tile-permuted (a random permutation from ``seed``).

    The grid is tiled from its south-west corner; the last row and column of tiles reach
    past the map and are filled by wrapping around it, so every cell gets a colour from a
    random tile and no border strip keeps its own."""
    if tile_cells < 1:
        raise ValueError(f"tile_cells must be ≥ 1, got {tile_cells}")
    h, w = bev.grid.shape
    n_r, n_c = -(-h // tile_cells), -(-w // tile_cells)
    rgb = np.pad(bev.channels[R:B + 1], ((0, 0), (0, n_r * tile_cells - h),
                                         (0, n_c * tile_cells - w)), mode="wrap")
    tiles = rgb.reshape(3, n_r, tile_cells, n_c, tile_cells).transpose(1, 3, 0, 2, 4)
    tiles = tiles.reshape(n_r * n_c, 3, tile_cells, tile_cells)
    order = np.random.default_rng(seed).permutation(n_r * n_c)
    out = tiles[order].reshape(n_r, n_c, 3, tile_cells, tile_cells).transpose(2, 0, 3, 1, 4)
    channels = bev.channels.copy()
    channels[R:B + 1] = out.reshape(3, n_r * tile_cells, n_c * tile_cells)[:, :h, :w]
    return dataclasses.replace(bev, channels=channels)

