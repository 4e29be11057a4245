"""The agent of the paper: E-UVFA inputs and networks, replay with task and goal relabelling,
competence and learning progress, the conditions compared, and the DDPG update."""
