"""Distractors are out of reach: the arm at full stretch, in every direction and at every
height, never touches a distractor cube, even one standing on the near edge of the region the
distractors may occupy; and that region lies on the table."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import suite
from suite import layout


def test_distractor_region_is_on_the_table():
    x_lo, x_hi = layout.DISTRACTOR_X_RANGE
    y_lo, y_hi = layout.DISTRACTOR_Y_RANGE
    table_lo = layout.TABLE_CENTRE[:2] - layout.TABLE_HALF_SIZE[:2]
    table_hi = layout.TABLE_CENTRE[:2] + layout.TABLE_HALF_SIZE[:2]
    half = layout.CUBE_HALF_SIZE
    assert table_lo[0] + half <= x_lo < x_hi <= table_hi[0] - half
    assert table_lo[1] + half <= y_lo < y_hi <= table_hi[1] - half
    starts = layout.DISTRACTOR_STARTS
    noise_x, noise_y = layout.DISTRACTOR_START_NOISE
    assert np.all(starts[:, 0] - noise_x >= x_lo)
    assert np.all(starts[:, 1] - noise_y >= y_lo)
    assert np.all(starts[:, 1] + noise_y <= y_hi)
    gaps = np.linalg.norm(starts[:, None] - starts[None], axis=-1) + np.eye(len(starts))
    assert gaps.min() > layout.DISTRACTOR_MIN_SEPARATION + 2 * np.hypot(noise_x, noise_y)


@pytest.mark.parametrize("variant", ["default", "distractors_7"])
def test_arm_at_full_stretch_cannot_touch_a_distractor(variant):
    env = suite.load(variant, seed=0)
    physics = env.physics
    model, data = physics.model.ptr, physics.data.ptr
    task = env.task
    distractor_geoms = {int(physics.bind(c.geom).element_id) for c in task.cubes[2:]}
    robot_geoms = [int(physics.bind(g).element_id) for g in task.robot.mjcf_model.find_all("geom")]
    mocap_ids = [int(model.body_mocapid[model.geom_bodyid[g]]) for g in sorted(distractor_geoms)]
    n = len(mocap_ids)
    # Line the distractors up on the near edge of their region, across the whole table.
    edge = np.c_[
        np.full(n, layout.DISTRACTOR_MIN_X),
        np.linspace(*layout.DISTRACTOR_Y_RANGE, n),
    ]
    fromto = np.zeros(6)
    closest = np.inf
    for ty in (0.0, 0.3, 0.55, 0.75, 0.95, 1.2, 1.5):
        for tz in (0.3, 0.45, 0.6, 0.9):
            env.reset()
            data.mocap_pos[mocap_ids, :2] = edge
            target = np.array([3.0, ty, tz])
            for _ in range(40):
                grip = data.site_xpos[physics.bind(task.robot.grip_site).element_id]
                action = np.r_[np.clip((target - grip) / 0.05, -1, 1), 1.0]  # fingers open
                env.step(action)
                for contact in data.contact[: data.ncon]:
                    pair = {int(contact.geom1), int(contact.geom2)}
                    assert not pair & distractor_geoms, "a distractor was touched"
            for g in robot_geoms:
                for d in distractor_geoms:
                    closest = min(closest, mujoco.mj_geomDistance(model, data, g, d, 0.5, fromto))
    # A margin, not a graze: measured about 8 cm.
    assert closest > 0.03, closest
