"""Multi-Task Fetch Arm: a dm_control composer task suite for multi-task, multi-goal RL."""
