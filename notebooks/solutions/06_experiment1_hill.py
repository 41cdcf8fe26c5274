"""Reference solution to notebook 06's exercise: the paper's outcome rule."""

GOAL_TOLERANCE_M = 5.0  # paper: "within 5 m of the goal"
IMMOBILE_LIMIT_S = 10.0  # paper: "immobilized for greater than 10 seconds"


def trial_outcome(goal_distance_m, immobile_s, done_reason, t_s, time_limit_s):
    """How a trial stands at one state: "success", "flipped", "diverged", "immobilized",
    "timeout" or "driving" (the rule checks in that order)."""
    if goal_distance_m <= GOAL_TOLERANCE_M:
        return "success"
    if done_reason is not None:
        return "flipped" if done_reason == "flipped" else "diverged"
    if immobile_s > IMMOBILE_LIMIT_S:
        return "immobilized"
    if t_s >= time_limit_s:
        return "timeout"
    return "driving"
