"""The achievable modules are achievable: scripted controllers, written here from the true positions
in the observation, succeed on reach, push_cube1, cube1_above_cube2 and stack from the env's
random starts and goals, and on the `sensor_failure` variant's push_cube1 and push_cube3. This
exercises the arm, the mocap weld, the fingers' grip on a cube (friction and contacts) and the
success predicates together."""

from __future__ import annotations

import numpy as np
import pytest

import suite

SEEDS = (0, 1, 2, 3, 4)


class PickAndPlace:
    """Open, go above cube 1, descend, close, carry it to its destination; for `stack`, release
    it there and lift the gripper away."""

    def __init__(self, module: str, slot: np.ndarray) -> None:
        self.module = module
        self.slot = np.asarray(slot, dtype=np.float64)
        self.phase = "approach"
        self.count = 0

    @staticmethod
    def move(gripper, target, fingers):
        return np.r_[np.clip((target - gripper) / 0.05, -1.0, 1.0), fingers]

    def destination(self, cube2):
        if self.module == "push_cube1":
            return self.slot
        if self.module == "cube1_above_cube2":
            return np.array([cube2[0], cube2[1], self.slot[2]])
        return cube2 + np.array([0.0, 0.0, 0.055])  # stack: just above its resting height

    def act(self, state: np.ndarray) -> np.ndarray:
        grip, cube1, cube2 = (state[i : i + 3].astype(np.float64) for i in (0, 3, 6))
        if self.module == "reach":
            return self.move(grip, self.slot, 1.0)
        if self.phase == "approach":
            target = cube1 + np.array([0.0, 0.0, 0.08])
            if np.linalg.norm((target - grip)[:2]) < 0.01 and abs(target[2] - grip[2]) < 0.02:
                self.phase = "descend"
            return self.move(grip, target, 1.0)
        if self.phase == "descend":
            if np.linalg.norm(cube1 - grip) < 0.01:
                self.phase = "close"
            return self.move(grip, cube1, 1.0)
        if self.phase == "close":
            self.count += 1
            if self.count >= 3:
                self.phase = "carry"
            return self.move(grip, cube1, -1.0)
        dest = self.destination(cube2)
        if self.phase == "carry":
            target = dest.copy()
            far = np.linalg.norm((dest - cube1)[:2]) > 0.02
            if self.module != "push_cube1" and far:
                target[2] = max(target[2], cube2[2] + 0.08)  # pass over cube 2
            if self.module == "stack" and not far and np.linalg.norm(dest - cube1) < 0.01:
                self.phase, self.count = "release", 0
            return self.move(grip, target + (grip - cube1), -1.0)
        self.count += 1  # release, then lift the gripper away
        if self.count < 3:
            return self.move(grip, grip, 1.0)
        return self.move(grip, cube1 + np.array([0.0, 0.0, 0.12]), 1.0)


@pytest.mark.parametrize("module", ["reach", "push_cube1", "cube1_above_cube2", "stack"])
def test_scripted_controller_succeeds_from_random_starts(module):
    env = suite.load("default", seed=11)
    index = env.task.module_index(module)
    for seed in SEEDS:
        env.task.set_next_episode(module=module, goal=np.random.default_rng(seed).uniform(-1, 1, 3))
        ts = env.reset()
        controller = PickAndPlace(module, env.task.goal_slots[index])
        rewards = []
        while not ts.last():
            ts = env.step(controller.act(ts.observation["state"]))
            rewards.append(ts.reward)
        assert ts.observation["success"][index] == 1.0, f"{module}, seed {seed}"
        assert rewards[-1] == 0.0
        if module in ("cube1_above_cube2", "stack"):
            cube1_z = ts.observation["state"][5]
            assert cube1_z > 0.46  # really lifted, not pushed


@pytest.mark.parametrize(("module", "cube"), [("push_cube1", 1), ("push_cube3", 3)])
def test_the_sensory_failure_variants_pushes_are_achievable(module, cube):
    """With three cubes on the table, the scripted controller still carries cube 1 or cube 3 to
    its goal: the module the sensory failure perturbs can be learned before the failure."""
    env = suite.load("sensor_failure", seed=11)
    index = env.task.module_index(module)
    for seed in SEEDS:
        env.task.set_next_episode(module=module, goal=np.random.default_rng(seed).uniform(-1, 1, 3))
        ts = env.reset()
        controller = PickAndPlace("push_cube1", env.task.goal_slots[index])
        while not ts.last():
            state = ts.observation["state"].copy()
            state[3:6] = state[3 * cube : 3 * cube + 3]  # the controller moves the cube at 3:6
            ts = env.step(controller.act(state))
        assert ts.observation["success"][index] == 1.0, f"{module}, seed {seed}"
