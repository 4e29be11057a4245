"""`MultiTaskFetch`: the composer task that holds a set of task modules.

Before an episode the caller may choose the active module and its goal
(`set_next_episode`); otherwise the env draws both uniformly. Goals are drawn for every module
at reset, so that `success` can be reported for all of them; the reward is the active module's.
Episodes last 50 steps and never end early (the last step has discount 1: a time limit, not a
terminal state).

Per control step the task does its work in two places: `before_step` turns the action into a
mocap target and finger command and moves the distractors, and the observation is computed in
one vectorised pass (state features, every module's outcome and success) the first time any
observable or the reward asks for it after the physics moved.

A task may have a sensory failure (`failing_cube`): switched on, the failing cube's perceived x
reads `layout.SENSOR_SHIFT_X` too far, and the whole observation (state, outcomes, success) and
the reward are computed from the perceived positions, as in the authors' perturbation study.
"""

from __future__ import annotations

import collections
import itertools
import math
from collections.abc import Sequence

import mujoco
import numpy as np
from dm_env import specs

from suite import layout
from suite.arena import TableArena
from suite.cube import Cube, cube_colour
from suite.distractors import DistractorWalk, start_positions
from suite.dm_composer import composer, observable
from suite.features import StateLayout, StateReader
from suite.fetch import FetchArm
from suite.layout import N_REACHABLE
from suite.modules import TaskModule, module_index
from suite.outcomes import ModuleEvaluator

OBSERVATION_KEYS = ("state", "achieved", "goal", "task", "success")
_STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION
_SETTLE_STEPS = 10  # control steps to settle the arm at construction, as the Fetch envs do


class _ArrayObservable(observable.Generic):
    """A task observable with a fixed float32 spec (so that no call is needed to infer it)."""

    def __init__(self, fn, shape: tuple[int, ...]) -> None:
        super().__init__(fn)
        self._spec = specs.Array(shape=shape, dtype=np.float32)

    @property
    def array_spec(self) -> specs.Array:
        return self._spec


class MultiTaskFetch(composer.Task):
    """The Multi-Task Fetch Arm: a Fetch arm, a wide table, cubes and a tuple of task modules.

    Args:
        modules: the task modules, in slot order (names must be unique).
        n_cubes: number of cubes: the first `n_reachable` are reachable, the others distractors.
        n_reachable: number of reachable cubes (free bodies placed near the gripper).
        failing_cube: 1-based number of the cube whose sensor can fail (`set_sensor_failure`);
            None for a task without a sensory failure.
    """

    restores_full_state = True
    """`initialize_episode` restores a complete MuJoCo state (the settled snapshot), so the
    environment may skip composer's default physics reset before it."""

    def __init__(
        self,
        modules: Sequence[TaskModule],
        *,
        n_cubes: int = 5,
        n_reachable: int = N_REACHABLE,
        failing_cube: int | None = None,
    ) -> None:
        self._modules = tuple(modules)
        self._check_modules(n_cubes)
        if not 1 <= n_reachable <= layout.MAX_REACHABLE:
            raise ValueError(
                f"n_reachable must be between 1 and {layout.MAX_REACHABLE}, got {n_reachable}"
            )
        if not n_reachable <= n_cubes <= n_reachable + layout.MAX_DISTRACTORS:
            raise ValueError(
                f"n_cubes must be between {n_reachable} and "
                f"{n_reachable + layout.MAX_DISTRACTORS} with {n_reachable} reachable cubes, "
                f"got {n_cubes}"
            )
        if failing_cube is not None and not 1 <= failing_cube <= n_cubes:
            raise ValueError(f"failing_cube must be a cube from 1 to {n_cubes}, got {failing_cube}")
        self._n_cubes = n_cubes
        self._n_reachable = n_reachable
        self._n_distractors = n_cubes - n_reachable
        self._failing_cube = failing_cube
        self._failure_bias = _failure_bias(n_cubes, failing_cube)
        self._sensor_on = False
        self._reader: StateReader | None = None

        self._arena = TableArena()
        self._robot = FetchArm()
        self._arena.attach(self._robot)
        self._cubes = tuple(
            Cube(f"cube{i + 1}", cube_colour(i, reachable=i < n_reachable)) for i in range(n_cubes)
        )
        # Reachable cubes are free bodies. Distractors are kinematic (mocap) bodies: the env
        # moves them by its random walk, so simulating their dynamics would only compute motion
        # that the next step overwrites; as mocap bodies they still collide with everything that
        # moves, but cost no degrees of freedom and no table contacts.
        self._cube_joints = []
        for i, cube in enumerate(self._cubes):
            frame = self._arena.attach(cube)
            # A resting spot in the compiled model (qpos0), so that composer's reset, which
            # computes the physics at qpos0 before the episode's state is set, finds no pile of
            # overlapping cubes to resolve.
            frame.pos = (*_parking_spot(i, n_reachable), layout.TABLE_TOP_Z + layout.CUBE_HALF_SIZE)
            if i < n_reachable:
                self._cube_joints.append(
                    frame.add(
                        "joint", type="free", name=f"{cube.mjcf_model.model}_free", damping=0.01
                    )
                )
            else:
                frame.mocap = True
        # The weld needs an explicit relpose: without one MuJoCo keeps the pose the two bodies
        # had in the compiled model, and the gripper would follow the mocap at that offset.
        self._arena.mjcf_model.equality.add(
            "weld",
            name="mocap_weld",
            body1=self._arena.mocap,
            body2=self._robot.gripper_body,
            relpose=(0, 0, 0, 1, 0, 0, 0),
            solimp=(0.9, 0.95, 0.001),
            solref=(0.02, 1),
        )
        self.set_timesteps(layout.CONTROL_TIMESTEP, layout.PHYSICS_TIMESTEP)

        # Sizes, slots and buffers that do not depend on the compiled physics.
        n_mod = len(self._modules)
        self._state_layout = StateLayout(n_cubes, n_reachable)
        self._evaluator = ModuleEvaluator(self._modules, n_cubes)
        self._outcome_slices = self._evaluator.slices
        self._state = np.zeros(self._state_layout.size, np.float32)
        self._achieved = self._evaluator.achieved
        self._goal_obs = np.zeros(3 * n_mod, np.float32)
        self._task_obs = np.zeros(n_mod, np.float32)
        self._success = self._evaluator.success
        self._goals = np.zeros((n_mod, 3), np.float32)
        self._slots = np.zeros((n_mod, 3), np.float32)
        self._active = 0
        self._reward = -1.0
        self._next_module: int | None = None
        self._next_goal: np.ndarray | None = None
        self._walk = DistractorWalk(n_cubes, self._n_distractors, layout.EPISODE_STEPS)
        self._steps = 0
        # The observation is computed once per (tick, physics time): ticks mark resets, steps
        # and switches; the time tells substeps apart when composer's own updater reads the
        # observables between substeps.
        self._tick = 0
        self._computed = (-1, -1.0)

        self._task_observables = collections.OrderedDict(
            (
                ("state", _ArrayObservable(self._observe_state, self._state.shape)),
                ("achieved", _ArrayObservable(self._observe_achieved, self._achieved.shape)),
                ("goal", _ArrayObservable(self._observe_goal, self._goal_obs.shape)),
                ("task", _ArrayObservable(self._observe_task, self._task_obs.shape)),
                ("success", _ArrayObservable(self._observe_success, self._success.shape)),
            )
        )
        for obs in self._task_observables.values():
            obs.enabled = True

    def _check_modules(self, n_cubes: int) -> None:
        if not self._modules:
            raise ValueError("a MultiTaskFetch task needs at least one module")
        names = [m.name for m in self._modules]
        if len(set(names)) != len(names):
            raise ValueError(f"module names must be unique, got {names}")
        for m in self._modules:
            if not isinstance(m, TaskModule):
                raise TypeError(f"modules must be suite.TaskModule, got {type(m).__name__}")
            if m.goal_dim != 3:
                raise ValueError(f"{m.name}: goal_dim must be 3, got {m.goal_dim}")
            if m.cubes and max(m.cubes) >= n_cubes:
                raise ValueError(
                    f"{m.name} watches cube {max(m.cubes) + 1} but the scene has {n_cubes} cubes"
                )

    # -- composer.Task interface ------------------------------------------------------------------

    @property
    def root_entity(self) -> TableArena:
        return self._arena

    @property
    def task_observables(self) -> collections.OrderedDict:
        return self._task_observables

    def action_spec(self, physics) -> specs.BoundedArray:
        """4-D action in [-1, 1]: gripper displacement (x, y, z) and the finger command."""
        return specs.BoundedArray(
            shape=(4,), dtype=np.float64, minimum=-1.0, maximum=1.0, name="dx\tdy\tdz\tgripper"
        )

    def get_reward_spec(self) -> specs.Array:
        return specs.Array(shape=(), dtype=np.float64, name="reward")

    def after_compile(self, physics, random_state) -> None:
        """Bind indices and array views to the new physics, settle the arm, snapshot it."""
        self._bind(physics)
        self._settle()

    def initialize_episode(self, physics, random_state) -> None:
        """Restore the settled snapshot, place the cubes, choose module and goals."""
        mujoco.mj_setState(self._m, self._d, self._snapshot, _STATE_SPEC)
        q = self._reach_qpos
        q[:, 2] = self._rest_z
        q[:, 3:] = (1.0, 0.0, 0.0, 0.0)
        q[:, :2] = self._reachable_start(random_state)
        self._reach_qvel[:] = 0.0
        if self._n_distractors:
            self._distractor_xy[:] = start_positions(self._n_distractors, random_state)
            self._walk.reset(random_state)
            self._distractor_pos[:, 2] = self._rest_z

        n_mod = len(self._modules)
        goals = random_state.uniform(-1.0, 1.0, size=(n_mod, 3)).astype(np.float32)
        if self._next_module is None:
            active = int(random_state.randint(n_mod))
        else:
            active = self._next_module
        if self._next_goal is not None:
            goals[active] = self._next_goal
        self._next_module = None
        self._next_goal = None
        self._active = active
        self._goals[:] = goals
        for i, m in enumerate(self._modules):
            self._slots[i] = m.slot_fn(goals[i])
        self._evaluator.set_slots(self._slots)
        self._goal_obs[:] = 0.0
        self._task_obs[:] = 0.0
        self._task_obs[active] = 1.0
        self._steps = 0
        self._tick += 1

    def before_step(self, physics, action, random_state) -> None:
        """Check the action, set the mocap target and the fingers, move the distractors."""
        a = self._check_action(action)
        # Like the Fetch envs: the mocap goes to the gripper's current position plus the
        # displacement (so it never runs away from a blocked gripper), and each finger's
        # position target is its current position plus the command (clamped by MuJoCo to the
        # actuator's range: closed or open).
        np.multiply(a[:3], layout.MAX_GRIPPER_DISPLACEMENT, out=self._delta)
        np.add(self._gripper_xpos, self._delta, out=self._arm_mocap_pos)
        np.add(self._finger_q, a[3], out=self._finger_ctrl)
        if self._n_distractors:
            self._distractor_xy[:] = self._walk.step(
                self._reach_xy, self._distractor_xy, random_state
            )

    def after_step(self, physics, random_state) -> None:
        self._steps += 1
        self._tick += 1

    def get_reward(self, physics) -> float:
        self._compute()
        return self._reward

    def should_terminate_episode(self, physics) -> bool:
        return self._steps >= layout.EPISODE_STEPS

    def get_discount(self, physics) -> float:
        return 1.0

    # -- the caller's controls --------------------------------------------------------------------

    def set_next_episode(
        self, module: int | str | None = None, goal: np.ndarray | Sequence[float] | None = None
    ) -> None:
        """Choose the module (index or name) and goal g in [-1, 1]^3 of the next episode.

        None leaves the choice to the env's uniform draw. Applies to the next reset only.
        """
        index = None if module is None else self.module_index(module)
        g = None
        if goal is not None:
            g = np.asarray(goal, dtype=np.float64)
            if g.shape != (3,):
                raise ValueError(f"goal must have shape (3,), got {g.shape}")
            if not np.all(np.isfinite(g)):
                raise ValueError(f"goal must be finite, got {g}")
            if np.any(np.abs(g) > 1.0):
                raise ValueError(f"goal must lie in [-1, 1]^3, got {g}")
            g = g.astype(np.float32)
        self._next_module = index
        self._next_goal = g

    def set_sensor_failure(self, on: bool) -> None:
        """Switch the sensory failure: the failing cube's perceived x reads 0.05 m too far.

        Takes effect from the next observation, in the state features and in the outcomes of
        the modules that read the cube (`sensor_failure_modules`), hence in their success and
        reward. The physics is untouched.
        """
        if self._failing_cube is None:
            raise ValueError(
                "this task has no sensory failure; load the 'sensor_failure' variant "
                "(or build MultiTaskFetch with failing_cube=...)"
            )
        self._sensor_on = bool(on)
        self._apply_sensor_failure()
        self._tick += 1

    def module_index(self, module: int | str) -> int:
        """Slot index of a module given by name or index (`suite.modules.module_index`: a
        ValueError listing the modules for unknown ones)."""
        return module_index(self.module_names, module)

    # -- read-only views --------------------------------------------------------------------------

    @property
    def modules(self) -> tuple[TaskModule, ...]:
        return self._modules

    @property
    def module_names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self._modules)

    @property
    def n_cubes(self) -> int:
        return self._n_cubes

    @property
    def n_reachable(self) -> int:
        """Number of reachable cubes: cubes 1..n_reachable; the others are distractors."""
        return self._n_reachable

    @property
    def state_layout(self) -> StateLayout:
        return self._state_layout

    @property
    def outcome_slices(self) -> tuple[slice, ...]:
        """One slice per module into the `achieved` vector."""
        return self._outcome_slices

    @property
    def active_module(self) -> int:
        """Slot index of this episode's module."""
        return self._active

    @property
    def goals(self) -> np.ndarray:
        """This episode's g in [-1, 1]^3 for every module, (n_modules, 3) float32 (a copy)."""
        return self._goals.copy()

    @property
    def goal_slots(self) -> np.ndarray:
        """This episode's goal slot for every module, (n_modules, 3) float32 (a copy): fixed for
        the episode; `goal_positions()` gives the goals they stand for now."""
        return self._slots.copy()

    def goal_positions(self) -> np.ndarray:
        """Every module's goal now, (n_modules, 3) float64, world frame: the slot, moved with
        cube 2's xy (as perceived) for the modules whose goal follows it
        (`TaskModule.goal`). What success is judged against."""
        self._compute()
        return self._evaluator.goals.astype(np.float64)

    @property
    def has_sensor_failure(self) -> bool:
        return self._failing_cube is not None

    @property
    def sensor_failure(self) -> bool:
        """Whether the sensory failure is switched on."""
        return self._sensor_on

    @property
    def position_bias(self) -> np.ndarray | None:
        """What the sensors add to the true positions [gripper, cube 1, ..., cube n] (flat,
        read-only): the failing cube's shift while the sensory failure is on, None otherwise."""
        return self._failure_bias if self._sensor_on else None

    @property
    def failing_cube(self) -> int | None:
        """1-based number of the cube whose sensor can fail; None without a sensory failure."""
        return self._failing_cube

    @property
    def sensor_failure_modules(self) -> tuple[str, ...]:
        """Names of the modules whose outcome reads the failing cube: those the failure
        perturbs (empty without a sensory failure)."""
        if self._failing_cube is None:
            return ()
        return tuple(m.name for m in self._modules if self._failing_cube - 1 in m.cubes)

    @property
    def sensor_failure_module(self) -> str | None:
        """The module the sensory failure perturbs, for a trainer to watch (`push_cube3` on the
        `sensor_failure` variant); None without a failure. Raises where it perturbs several."""
        names = self.sensor_failure_modules
        if len(names) > 1:
            raise ValueError(
                f"the sensory failure perturbs several modules ({', '.join(names)}); "
                "use sensor_failure_modules"
            )
        return names[0] if names else None

    @property
    def distractor_walk(self) -> DistractorWalk:
        """The distractors' random walk, this episode's steps drawn (`before_step` steps it)."""
        return self._walk

    @property
    def arena(self) -> TableArena:
        return self._arena

    @property
    def robot(self) -> FetchArm:
        return self._robot

    @property
    def cubes(self) -> tuple[Cube, ...]:
        return self._cubes

    @property
    def initial_gripper_pos(self) -> np.ndarray:
        """Where the grip site starts every episode (measured after settling)."""
        return self._grip0.copy()

    # -- internals --------------------------------------------------------------------------------

    def _bind(self, physics) -> None:
        m, d = physics.model.ptr, physics.data.ptr
        self._m, self._d = m, d
        self._gripper_body = int(physics.bind(self._robot.gripper_body).element_id)
        grip_site = int(physics.bind(self._robot.grip_site).element_id)
        qadr = np.array([physics.bind(j).qposadr for j in self._cube_joints]).ravel()
        vadr = np.array([physics.bind(j).dofadr for j in self._cube_joints]).ravel()
        if not (np.all(np.diff(qadr) == 7) and np.all(np.diff(vadr) == 6)):
            raise RuntimeError("the cubes' free joints are expected to be contiguous in qpos")
        n_reach = self._n_reachable
        self._reach_qpos = d.qpos[qadr[0] : qadr[0] + 7 * n_reach].reshape(n_reach, 7)
        self._reach_qvel = d.qvel[vadr[0] : vadr[0] + 6 * n_reach].reshape(n_reach, 6)
        cube_bodies = np.array(
            [m.geom_bodyid[physics.bind(c.geom).element_id] for c in self._cubes], dtype=np.intp
        )
        mocap_ids = m.body_mocapid[cube_bodies[n_reach:]]
        if self._n_distractors and not (np.all(mocap_ids >= 0) and np.all(np.diff(mocap_ids) == 1)):
            raise RuntimeError("the distractors' mocap bodies are expected to be consecutive")
        first = int(mocap_ids[0]) if self._n_distractors else 0
        self._distractor_pos = d.mocap_pos[first : first + self._n_distractors]
        self._distractor_xy = self._distractor_pos[:, :2]
        self._reach_xy = self._reach_qpos[:, :2]
        # (dm_control cannot `bind` a mocap body, so look it up by name.)
        mocap_body = physics.model.name2id(self._arena.mocap.full_identifier, "body")
        arm_mocap = int(m.body_mocapid[mocap_body])
        self._arm_mocap_pos = d.mocap_pos[arm_mocap]
        self._arm_mocap_quat = d.mocap_quat[arm_mocap]
        self._gripper_xpos = d.xpos[self._gripper_body]
        self._delta = np.zeros(3)
        fq = [int(physics.bind(j).qposadr) for j in self._robot.finger_joints]
        fv = [int(physics.bind(j).dofadr) for j in self._robot.finger_joints]
        fa = [int(physics.bind(a).element_id) for a in self._robot.finger_actuators]
        self._finger_qpos = _as_slice(fq, "finger joints in qpos")
        self._finger_qvel = _as_slice(fv, "finger joints in qvel")
        self._finger_q = d.qpos[self._finger_qpos]
        self._finger_ctrl = d.ctrl[_as_slice(fa, "finger actuators")]
        self._reader = StateReader(
            m,
            d,
            grip_site=grip_site,
            reach_bodies=cube_bodies[:n_reach],
            reach_qpos=self._reach_qpos,
            distractor_pos=self._distractor_pos,
            finger_qpos=self._finger_qpos,
            finger_qvel=self._finger_qvel,
        )
        self._grip_site = grip_site
        self._apply_sensor_failure()
        self._computed = (-1, -1.0)

    def _apply_sensor_failure(self) -> None:
        """Hand the reader the failing cube's bias while the failure is on (none otherwise)."""
        if self._reader is not None:
            self._reader.position_bias = self.position_bias

    def _settle(self) -> None:
        """Bring the arm to its start pose once; every reset restores this snapshot."""
        m, d = self._m, self._d
        mujoco.mj_resetData(m, d)
        mujoco.mj_forward(m, d)
        # Start the mocap on the gripper (no jerk), then move it so that the grip site lands on
        # GRIP0 (the grip site is 0.02 below the gripper link with the fingers pointing down).
        self._arm_mocap_pos[:] = d.xpos[self._gripper_body]
        self._arm_mocap_quat[:] = d.xquat[self._gripper_body]
        mujoco.mj_forward(m, d)
        self._arm_mocap_pos[:] = layout.GRIP0 + np.array([0.0, 0.0, 0.02])
        self._arm_mocap_quat[:] = layout.GRIPPER_QUAT
        for _ in range(_SETTLE_STEPS):
            mujoco.mj_step(m, d, nstep=layout.SUBSTEPS)
        d.time = 0.0
        mujoco.mj_forward(m, d)
        self._rest_z = float(np.mean(self._reach_qpos[:, 2]))
        self._distractor_pos[:, 2] = self._rest_z
        self._grip0 = d.site_xpos[self._grip_site].copy()
        self._snapshot = np.empty(mujoco.mj_stateSize(m, _STATE_SPEC))
        mujoco.mj_getState(m, d, self._snapshot, _STATE_SPEC)

    def _reachable_start(self, random_state: np.random.RandomState) -> np.ndarray:
        """xy of the reachable cubes, one after the other: grip0_xy + U(-0.15, 0.15)^2, redrawn
        until >= 0.1 from the gripper and from the cubes already placed (as the authors do)."""
        cx, cy = (float(v) for v in self._grip0[:2])
        sep = layout.OBJECT_MIN_SEPARATION
        placed: list[tuple[float, float]] = []
        while len(placed) < self._n_reachable:
            dx, dy = random_state.uniform(-layout.OBJECT_RANGE, layout.OBJECT_RANGE, size=2)
            x, y = cx + float(dx), cy + float(dy)
            if math.hypot(x - cx, y - cy) < sep:
                continue
            if any(math.hypot(x - px, y - py) < sep for px, py in placed):
                continue
            placed.append((x, y))
        return np.array(placed)

    def _check_action(self, action) -> np.ndarray:
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (4,):
            raise ValueError(f"action must have shape (4,), got {a.shape}")
        x, y, z, f = a.tolist()
        # (Plain comparisons: a numpy reduction costs more than the rest of this check. They
        # are all False for NaN.)
        if not (-1.0 <= x <= 1.0 and -1.0 <= y <= 1.0 and -1.0 <= z <= 1.0 and -1.0 <= f <= 1.0):
            if not np.all(np.isfinite(a)):
                raise ValueError(f"action must be finite, got {a}")
            a = np.clip(a, -1.0, 1.0)
        return a

    def _compute(self) -> None:
        """State features, outcomes and success of every module, once per tick."""
        key = (self._tick, self._d.time)
        if self._computed == key:
            return
        reader = self._reader
        reader.read(self._state)
        self._evaluator.evaluate(reader.positions, reader.gripper, reader.cubes)
        a = self._active
        self._goal_obs[3 * a : 3 * a + 3] = self._evaluator.goals[a]
        self._reward = -1.0 + float(self._success[a])
        self._computed = key

    def _observe_state(self, physics) -> np.ndarray:
        self._compute()
        return self._state

    def _observe_achieved(self, physics) -> np.ndarray:
        self._compute()
        return self._achieved

    def _observe_goal(self, physics) -> np.ndarray:
        self._compute()
        return self._goal_obs

    def _observe_task(self, physics) -> np.ndarray:
        return self._task_obs

    def _observe_success(self, physics) -> np.ndarray:
        self._compute()
        return self._success


def _parking_spot(cube: int, n_reachable: int) -> tuple[float, float]:
    """xy where cube `cube` (0-based) sits in the compiled model: reachable cubes around the
    gripper's start, distractors on their start points."""
    if cube < n_reachable:
        x, y = layout.GRIP0[:2] + layout.REACHABLE_PARKING[cube]
    else:
        x, y = layout.DISTRACTOR_STARTS[cube - n_reachable]
    return float(x), float(y)


def _failure_bias(n_cubes: int, failing_cube: int | None) -> np.ndarray:
    """What the failing sensor adds to [gripper, cube 1, ..., cube n] (flat): the shift on the
    failing cube's x (zero without a failing cube)."""
    bias = np.zeros(3 + 3 * n_cubes)
    if failing_cube is not None:
        bias[3 * failing_cube] = layout.SENSOR_SHIFT_X
    bias.setflags(write=False)
    return bias


def _as_slice(indices: list[int], what: str) -> slice:
    """The slice covering consecutive indices, ascending or descending (so that views can be
    held on MuJoCo's arrays)."""
    steps = {b - a for a, b in itertools.pairwise(indices)}
    if len(indices) == 1 or steps == {1}:
        return slice(indices[0], indices[-1] + 1)
    if steps == {-1}:
        stop = indices[-1] - 1
        return slice(indices[0], None if stop < 0 else stop, -1)
    raise RuntimeError(f"the {what} are expected to be consecutive, got {indices}")
