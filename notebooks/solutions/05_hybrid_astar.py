"""Reference solutions of notebook 05 (Hybrid A* on a directional costmap)."""


def my_edge_cost(length_m: float, cost: float, beta: float) -> float:
    """g_edge [m] of a move of length s = ``length_m`` [m] over looked-up cost C = ``cost``
    with amplification β = ``beta`` (paper): C' = C(1 + βC), g_edge = s(1 + C')."""
    amplified = cost * (1.0 + beta * cost)
    return length_m * (1.0 + amplified)
