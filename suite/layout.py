"""The numbers of the Multi-Task Fetch Arm scene (paper §2 and §6.2; docs/suite.md).

Every length is in metres, in the world frame. The entities, the task modules and the
distractor walk all read their geometry from here, so that a number is stated once.
"""

from __future__ import annotations

import numpy as np

# Time.
PHYSICS_TIMESTEP = 0.002
SUBSTEPS = 20
CONTROL_TIMESTEP = PHYSICS_TIMESTEP * SUBSTEPS  # 0.04 s per env step
EPISODE_STEPS = 50

# Action: the gripper moves at most this far per env step (through the mocap).
MAX_GRIPPER_DISPLACEMENT = 0.05
# Fixed gripper orientation (wxyz, normalised): fingers pointing down, as in the Fetch envs.
GRIPPER_QUAT = np.array([1.0, 0.0, 1.0, 0.0]) / np.sqrt(2.0)

# The Fetch base sits where the gymnasium-robotics Fetch envs park it (their slide joints
# 0.405, 0.48 added to the base body's position); the base is fixed here.
FETCH_BASE_POS = (0.2869 + 0.405, 0.2641 + 0.48, 0.0)

# The wide table (wider than the stock Fetch table so that out-of-reach cubes sit on it).
TABLE_CENTRE = np.array([1.65, 0.75, 0.2])
TABLE_HALF_SIZE = np.array([0.6, 0.45, 0.2])
TABLE_TOP_Z = float(TABLE_CENTRE[2] + TABLE_HALF_SIZE[2])  # 0.40

# Cubes.
CUBE_HALF_SIZE = 0.025
CUBE_MASS = 2.0
CUBE_REST_Z = 0.426  # nominal resting height of a cube centre on the table (goal slots use it)

# Where the gripper's grip site starts every episode (the arm is settled there once).
GRIP0 = np.array([1.342, 0.749, 0.535])

# Reachable cubes start at GRIP0_xy + U(-range, range)^2, at least `min_sep` from the gripper's
# xy and from each other.
OBJECT_RANGE = 0.15
OBJECT_MIN_SEPARATION = 0.1
# Where reachable cubes 1, 2, 3 rest in the compiled model (offsets from GRIP0_xy): apart, clear
# of the arm, inside the start region. A scene has at most one reachable cube per spot.
REACHABLE_PARKING = np.array([[-0.1, -0.1], [0.1, 0.1], [0.1, -0.1]])
MAX_REACHABLE = len(REACHABLE_PARKING)
N_REACHABLE = 2
"""Reachable cubes of the paper's environment: cube 1 (manipulated) and cube 2 (the base)."""

# Distractors: start points (x, y), in the order the distractors (the cubes after the reachable
# ones: cubes 3, 4, 5, ... in the paper's env) take them. The first three are the paper's; the
# others serve the variants with 4 and 7 distractors.
DISTRACTOR_STARTS = np.array(
    [
        [2.00, 0.65],
        [1.90, 0.80],
        [2.00, 0.90],
        [2.15, 0.75],
        [1.95, 0.45],
        [1.95, 1.05],
        [2.15, 1.05],
    ]
)
# Each start point gets x + U(-0.01, 0.01), y + U(-0.02, 0.02) (gym_flowers
# multi_task_fetch_arm_v0.py, `_reset_sim`).
DISTRACTOR_START_NOISE = np.array([0.01, 0.02])
DISTRACTOR_WALK_STD = 0.005  # xy += N(0, std^2) every env step (v0.py, `_get_obs`)
DISTRACTOR_MIN_SEPARATION = 0.05  # a walk move ending closer than this to another cube is redrawn
# Moves drawn and checked in a step, then the distractor stays put (v0.py gives up at i == 100).
DISTRACTOR_MAX_DRAWS = 99
# The region a distractor centre may occupy: on the table with a margin, and beyond the arm's
# reach (x >= DISTRACTOR_MIN_X; tests/test_suite_reach.py checks the arm at full stretch cannot
# touch a cube there).
DISTRACTOR_MIN_X = 1.85
DISTRACTOR_MARGIN = 0.04
DISTRACTOR_X_RANGE = (
    DISTRACTOR_MIN_X,
    float(TABLE_CENTRE[0] + TABLE_HALF_SIZE[0]) - DISTRACTOR_MARGIN,
)
DISTRACTOR_Y_RANGE = (
    float(TABLE_CENTRE[1] - TABLE_HALF_SIZE[1]) + DISTRACTOR_MARGIN,
    float(TABLE_CENTRE[1] + TABLE_HALF_SIZE[1]) - DISTRACTOR_MARGIN,
)

MAX_DISTRACTORS = len(DISTRACTOR_STARTS)

# Success threshold of every module (distance to the goal; gym_flowers __init__ registration of
# MultiTaskFetchArm-v0, `distance_threshold=0.05`).
SUCCESS_DISTANCE = 0.05
# `stack`'s guard: the gripper must be at least this far from the goal (v0.py, compute_reward:
# `dgrip < distance_threshold` fails). The later v5 (2019) raised it to 1.2 x 0.05; the paper's
# environment is v0.
STACK_GRIPPER_AWAY = SUCCESS_DISTANCE

# Sensory failure: the perceived x of the failing cube reads this much too far, in the state and
# in every outcome (gym_flowers multi_task_fetch_arm_v3.py, `object2_pos[0] += 0.05`).
SENSOR_SHIFT_X = 0.05
