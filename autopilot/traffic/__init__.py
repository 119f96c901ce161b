"""Traffic encounters (issue 18): scoring a run against the rules (:mod:`.score`, pure on trajectories) and a
small closed-loop kinematic simulation of own ship and targets (:mod:`.sim`) for tests and quick studies.

The real model, GNC and operator modes run encounters in ``autopilot evaluate --traffic``; they score
their runs with the same :func:`autopilot.traffic.score.score_encounter`.
"""
