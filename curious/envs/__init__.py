"""The agent's view of an environment: the goal-env protocol, copies stepped together, rollouts."""
