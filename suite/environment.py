"""`SuiteEnvironment`: a composer.Environment that runs a control step's substeps in one call.

composer.Environment advances a control step as a Python loop over physics substeps, calling the
substep hooks and the observation updater around each one. When no task, entity or extra hook
acts between substeps and every observable is read once per control step (buffer 1, no delay,
update every step, no aggregator), that loop does nothing but call `physics.step()` 20 times;
this environment then makes a single `physics.step(n_substeps)` call instead (same MuJoCo
stepping, composer's legacy stepping, so positions and velocities are up to date when the hooks
and observables read them) and reads each observable once. Otherwise it falls back to
composer's own step, unchanged. Everything else (reset, specs, hooks) is composer's.

The physics call itself goes straight to MuJoCo (`mj_step2`, `mj_step`, `mj_step1`, exactly
what `Physics.step` calls) with a cheaper check for MuJoCo warnings that raises the same
`PhysicsError`: dm_control's wrapper costs about 45 us per call on a 2-core machine, a tenth
of a control step here. For tasks that restore a complete MuJoCo state at reset
(`task.restores_full_state`), the reset skips composer's default physics reset, whose work
the task would throw away.

That speed rests on composer internals (hook containers, the reset attempt, the observation
updater), so `make_environment` uses it only with the dm_control release it was checked against
(`FAST_PATH_DM_CONTROL`; a test compares it with stock composer step for step on every variant)
and gives a stock `composer.Environment` otherwise, or when asked (`stock=True`, or the
environment variable `SUITE_STOCK_COMPOSER=1`).
"""

from __future__ import annotations

import collections
import importlib.metadata
import os
import warnings

import dm_env
import mujoco
import numpy as np
from dm_control.rl import control

from suite.dm_composer import composer, composer_environment, observation_updater

_SUBSTEP_HOOKS = ("before_substep", "after_substep")

FAST_PATH_DM_CONTROL = "1.0.50"
"""The dm_control release `SuiteEnvironment` was checked against."""


def fast_path_supported() -> bool:
    """Whether the installed dm_control is the release the fast path was checked against."""
    try:
        return importlib.metadata.version("dm-control") == FAST_PATH_DM_CONTROL
    except importlib.metadata.PackageNotFoundError:
        return False


def make_environment(
    task: composer.Task, random_state=None, *, stock: bool = False, **kwargs
) -> composer.Environment:
    """The environment of a suite task: `SuiteEnvironment`, or a stock `composer.Environment`
    with the same settings when `stock` (or `SUITE_STOCK_COMPOSER=1`) asks for it or the
    installed dm_control is not the release the fast path was checked against (with a warning).
    Both give the same episodes step for step."""
    kwargs.setdefault("recompile_mjcf_every_episode", False)
    kwargs.setdefault("strip_singleton_obs_buffer_dim", True)
    stock = stock or os.environ.get("SUITE_STOCK_COMPOSER", "") not in ("", "0")
    if not stock and not fast_path_supported():
        warnings.warn(
            f"dm_control is not {FAST_PATH_DM_CONTROL}, the release the suite's fast step was "
            "checked against: using composer's own step (slower, same episodes)",
            stacklevel=2,
        )
        stock = True
    if stock:
        return composer.Environment(task, random_state=random_state, **kwargs)
    return SuiteEnvironment(task, random_state=random_state, **kwargs)


class OncePerStepUpdater:
    """Observation updater for observables read once per control step, without buffering.

    Offers the interface of composer's `observation.Updater` that the environment uses.
    """

    def __init__(self, observables: dict, strip_singleton_buffer_dim: bool) -> None:
        self._observables = observables
        self._strip = strip_singleton_buffer_dim
        self._callables: list[tuple[str, object]] = []
        self._specs: collections.OrderedDict | None = None
        self._bound_to: tuple | None = None

    @staticmethod
    def supports(observables) -> bool:
        """Whether every enabled observable can be read once per control step."""
        if not isinstance(observables, dict):
            return False
        for obs in observables.values():
            if not obs.enabled:
                continue
            if obs.aggregator is not None:
                return False
            if obs.buffer_size not in (None, 1) or obs.delay not in (None, 0):
                return False
            if obs.update_interval not in (None, 1):
                return False
        return True

    def reset(self, physics, random_state) -> None:
        """Bind every enabled observable to `physics` (once per physics: binding is pure)."""
        key = (
            id(physics),
            id(random_state),
            tuple(name for name, obs in self._observables.items() if obs.enabled),
        )
        if self._bound_to == key and self._specs is not None:
            return
        self._callables = []
        specs = collections.OrderedDict()
        for name, obs in self._observables.items():
            if not obs.enabled:
                continue
            fn = obs.observation_callable(physics, random_state)
            spec = obs.array_spec
            if spec is None:
                value = np.asarray(fn())
                spec = dm_env.specs.Array(value.shape, value.dtype)
            shape = spec.shape if self._strip else (1, *spec.shape)
            specs[name] = dm_env.specs.Array(shape=shape, dtype=spec.dtype, name=name)
            self._callables.append((name, fn))
        self._specs = specs
        self._bound_to = key

    @property
    def observables(self) -> dict:
        """The observables this updater was built with (as composer's updater, it reads their
        options again at every reset)."""
        return self._observables

    def observation_spec(self) -> collections.OrderedDict:
        if self._specs is None:
            raise RuntimeError("`reset` must be called before `observation_spec`.")
        return collections.OrderedDict(self._specs)

    def prepare_for_next_control_step(self) -> None:
        """Nothing to schedule: every observable is read once, after the step."""

    def update(self) -> None:
        """Nothing to buffer: observables are read by `get_observation`."""

    def get_observation(self) -> collections.OrderedDict:
        if self._specs is None:
            raise RuntimeError("`reset` must be called before `get_observation`.")
        out = collections.OrderedDict()
        if self._strip:
            for name, fn in self._callables:
                out[name] = np.array(fn())
        else:
            for name, fn in self._callables:
                out[name] = np.array(fn())[None]
        return out


class SuiteEnvironment(composer.Environment):
    """composer.Environment with a single physics call per control step where that is exact.

    Defaults differ from composer's where the suite needs it: the MJCF is compiled once (the
    model does not change between episodes) and observations carry no singleton buffer
    dimension.
    """

    def __init__(self, task: composer.Task, random_state=None, **kwargs) -> None:
        kwargs.setdefault("recompile_mjcf_every_episode", False)
        kwargs.setdefault("strip_singleton_obs_buffer_dim", True)
        self._fast_observation = False
        self._single_call: bool | None = None
        self._raw: tuple | None = None
        super().__init__(task, random_state=random_state, **kwargs)
        if self._task_model_is_static():
            # The constructor has just compiled the model and nothing edits it per episode, so
            # composer's compile-again-at-first-reset would only repeat the work.
            self._mjcf_never_compiled = False

    def _task_model_is_static(self) -> bool:
        if self._recompile_mjcf_every_episode:
            return False
        task_hook = type(self._task).initialize_episode_mjcf
        if task_hook is not composer.Task.initialize_episode_mjcf and not (
            composer_environment._callable_is_trivial(task_hook)
        ):
            return False
        hooks = self._hooks._initialize_episode_mjcf
        return not hooks.entity_hooks and not hooks.extra_hooks

    def _recompile_physics_and_update_observables(self) -> None:
        super()._recompile_physics_and_update_observables()
        physics = self._physics
        rk4 = physics.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4.value
        self._raw = (
            physics.model.ptr,
            physics.data.ptr,
            physics.data.ptr.warning.number,
            bool(physics.legacy_step) and not rk4,
        )
        self._single_call = None

    def _make_observation_updater(self):
        observables = self._task.observables
        self._fast_observation = OncePerStepUpdater.supports(observables)
        if self._fast_observation:
            return OncePerStepUpdater(observables, self._strip_singleton_obs_buffer_dim)
        return observation_updater.Updater(
            observables,
            self._task.physics_steps_per_control_step,
            self._strip_singleton_obs_buffer_dim,
            self._delayed_observation_padding == composer.ObservationPadding.INITIAL_VALUE,
        )

    def reset(self) -> dm_env.TimeStep:
        """Start an episode (composer's reset). Observable options changed since the last reset
        are honoured: the updater is rebuilt when they no longer allow one read per step."""
        updater = self._observation_updater
        if self._fast_observation and not OncePerStepUpdater.supports(updater.observables):
            self._observation_updater = self._make_observation_updater()
            self._single_call = None
        return super().reset()

    def _reset_attempt(self) -> dm_env.TimeStep:
        """composer's reset, minus the default physics reset when the task restores a complete
        MuJoCo state itself (`task.restores_full_state`): zeroing the data and computing the
        physics at qpos0 would then only be thrown away."""
        if (
            not getattr(self._task, "restores_full_state", False)
            or self._recompile_mjcf_every_episode
            or self._mjcf_never_compiled
        ):
            return super()._reset_attempt()
        if self._fixed_initial_state:
            self._random_state.set_state(self._fixed_random_state)
        self._hooks.initialize_episode(self._physics_proxy, self._random_state)
        self._forward_without_actuation()
        self._observation_updater.reset(self._physics_proxy, self._random_state)
        self._reset_next_step = False
        return dm_env.TimeStep(
            step_type=dm_env.StepType.FIRST,
            reward=None,
            discount=None,
            observation=self._observation_updater.get_observation(),
        )

    def add_extra_hook(self, hook_name, hook_callable) -> None:
        super().add_extra_hook(hook_name, hook_callable)
        self._single_call = None

    @property
    def single_call_stepping(self) -> bool:
        """Whether the next control step runs all its substeps in one physics call."""
        if self._single_call is None:
            self._single_call = self._can_step_in_one_call()
        return self._single_call

    def _can_step_in_one_call(self) -> bool:
        if not self._fast_observation or self._overridden_n_sub_steps is not None:
            return False
        task_type = type(self._task)
        for hook_name in _SUBSTEP_HOOKS:
            if getattr(task_type, hook_name) is not getattr(composer.Task, hook_name):
                if not composer_environment._callable_is_trivial(getattr(task_type, hook_name)):
                    return False
            hook = getattr(self._hooks, "_" + hook_name)
            if hook.entity_hooks or hook.extra_hooks:
                return False
        return True

    def step(self, action) -> dm_env.TimeStep:
        """Advance one control step (one physics call for all substeps when exact)."""
        if self._reset_next_step or not self.single_call_stepping:
            return super().step(action)

        proxy = self._physics_proxy
        self._hooks.before_step(proxy, action, self._random_state)
        try:
            self._advance_physics()
            physics_is_divergent = False
        except control.PhysicsError as e:
            if self._raise_exception_on_physics_error:
                raise
            composer_environment.logging.warning(e)
            physics_is_divergent = True
        self._hooks.after_step(proxy, self._random_state)

        task = self._task
        if not physics_is_divergent:
            reward = task.get_reward(proxy)
            discount = task.get_discount(proxy)
            terminating = task.should_terminate_episode(proxy) or (
                self._raw[1].time >= self._time_limit
            )
        else:
            reward, discount, terminating = 0.0, 0.0, True

        obs = self._observation_updater.get_observation()
        if not terminating:
            return dm_env.TimeStep(dm_env.StepType.MID, reward, discount, obs)
        self._reset_next_step = True
        return dm_env.TimeStep(dm_env.StepType.LAST, reward, discount, obs)

    def _forward_without_actuation(self) -> None:
        """`Physics.after_reset`, straight to MuJoCo: `mj_forward` with actuation disabled."""
        model, data, warnings, _ = self._raw
        before = int(warnings.sum())
        flags = model.opt.disableflags
        model.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
        try:
            mujoco.mj_forward(model, data)
        finally:
            model.opt.disableflags = flags
        self._check_warnings(before)

    def _check_warnings(self, before: int) -> None:
        """Raise dm_control's PhysicsError if MuJoCo raised a warning since `before`."""
        warnings = self._raw[2]
        if int(warnings.sum()) > before:
            kinds = list(mujoco.mjtWarning.__members__)
            names = [kind for kind, count in zip(kinds, warnings, strict=False) if count]
            raise control.PhysicsError(
                "Physics state is invalid. Warning(s) raised: " + ", ".join(names)
            )

    def _advance_physics(self) -> None:
        """All substeps of one control step in one go, as `Physics.step(n)` would run them."""
        model, data, warnings, legacy = self._raw
        n = self._n_sub_steps
        before = int(warnings.sum())
        if legacy:
            # Finish the step whose first half the last mj_step1 computed, take the other
            # substeps, and leave position- and velocity-dependent quantities up to date.
            mujoco.mj_step2(model, data)
            if n > 1:
                mujoco.mj_step(model, data, n - 1)
            mujoco.mj_step1(model, data)
        else:
            mujoco.mj_step(model, data, n)
        if int(warnings.sum()) > before:
            self._check_warnings(before)
