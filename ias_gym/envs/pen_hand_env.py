"""What both pen tasks share: the MuJoCo hand holding the pen, stepping, safety, rendering.

A task subclass (:mod:`ias_gym.envs.pen_slide`, :mod:`ias_gym.envs.pen_rotate`) says only
what differs: its configuration, the reset distribution, its reference motion, observation
features, reward terms and success test (dm_control's Physics/Task split). The physics
questions a controller asks (W, J, M, H, ...) are answered by :class:`PenHandPhysics`
(``env.physics``); the env itself reads only what an observation needs, once per step, from
MuJoCo's arrays and sensors (:class:`PenState`, read by
:class:`~ias_gym.envs.pen_observation.PenStateReader`), because ``env.step`` should cost
little more than the simulation it runs (``bench/bench_envs.py``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ias_gym.envs.disturbances import DisturbanceSettings, DisturbanceState, SensorNoise
from ias_gym.envs.layout import ObservationParts, layout_size, observation_layout
from ias_gym.envs.mujoco_state import (
    integration_state,
    restore_integration_state,
    set_state_from_options,
)
from ias_gym.envs.pen_hand_types import FloatArray, PenHandConfig, PenReference, PenState
from ias_gym.envs.pen_observation import (
    TO_PAPER_INDEX,
    PenStateReader,
    as_index,
    pen_observation_parts,
)
from ias_gym.envs.window import check_window_possible
from ias_gym.errors import InputError
from ias_gym.sim.grasp_pose import place_grasp
from ias_gym.sim.hands import HANDS, get_hand
from ias_gym.sim.pen_hand import PenHandPhysics, load_pen_hand_model

#: The paper's contact layout along the pen, ``[-phi1, -phi2, +phi3, +phi4]`` at t = 0 [m]
#: (the four-finger hand's; each hand's is ``HandSpec.contact_x``).
NOMINAL_CONTACT_X = np.array(HANDS["ias4f"].contact_x)
#: Shaping scales (reward terms are exp(-(error / scale)^2), bounded in [0, 1]).
POSITION_SCALE = 0.005  # [m]
ANGLE_SCALE = math.radians(5.0)  # [rad]


class PenHandEnv(gym.Env[FloatArray, NDArray[Any]]):
    """Base class of the pen tasks (not registered itself).

    Action: ``Box(-1, 1, (n,))``, joint torques normalised by each motor's limit, the hand's
    joints in order (``config.hand``, :mod:`ias_gym.sim.hands`; four-finger hand: n = 12,
    0.5 N m motors). Out-of-range values are clipped; NaN or inf raise ``ValueError``.
    Contacts are sampled once per step (``control_dt``): a contact gap is measured in whole
    control periods.

    Observation: the parts of :func:`~ias_gym.envs.pen_observation.pen_observation_parts`,
    then the task's (:meth:`_task_observation_parts`); by name in :attr:`observation_layout`
    (``obs[env.observation_layout["pen_position"]]``).
    """

    metadata = {  # noqa: RUF012  (gymnasium's convention)
        "render_modes": ["human", "rgb_array", "depth_array"],
        "render_fps": 100,
    }
    config_class: ClassVar[type[PenHandConfig]] = PenHandConfig
    #: Attributes that make up an episode's state (pickled with the env).
    _episode_fields: ClassVar[tuple[str, ...]] = (
        "_steps",
        "_gap",
        "_max_gap",
        "_max_position_error",
        "_dropped",
        "_unstable",
        "_last_action",
        "disturbances",
    )

    # Episode state (see _start_episode).
    _steps: int
    _gap: FloatArray
    _max_gap: FloatArray
    _max_position_error: float
    _dropped: bool
    _unstable: bool
    _last_action: FloatArray
    state: PenState

    def __init__(self, render_mode: str | None = None, **config: Any) -> None:
        """Build the task.

        Args:
            render_mode: ``None``, ``"human"``, ``"rgb_array"`` or ``"depth_array"``.
            **config: fields of the task's configuration dataclass to override.
        """
        fields = {f.name for f in dataclasses.fields(self.config_class)}
        unknown = sorted(set(config) - fields)
        if unknown:
            raise TypeError(
                f"unknown config {unknown} for {type(self).__name__}; known: {sorted(fields)}"
            )
        self.config = self.config_class(**config)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InputError(
                f"render_mode {render_mode!r} is not one of {self.metadata['render_modes']}"
            )
        if render_mode == "human":
            check_window_possible()
        self.render_mode = render_mode

        #: The robot hand's layout (:mod:`ias_gym.sim.hands`).
        self.hand = get_hand(self.config.hand)
        self.model = load_pen_hand_model(self.hand.scene)
        self.data = mujoco.MjData(self.model)
        self.physics = PenHandPhysics(
            self.model,
            self.data,
            self.hand.fingers,
            finger_joints=self.hand.joints,
            sides=self.hand.sides,
        )
        timestep = self.model.opt.timestep
        self.frame_skip = round(self.config.control_dt / timestep)
        if self.frame_skip < 1 or not math.isclose(
            self.frame_skip * timestep, self.config.control_dt
        ):
            raise ValueError(
                f"control_dt={self.config.control_dt} s must be a multiple of the physics "
                f"step {timestep} s"
            )
        self.max_steps = round(self.config.duration / self.config.control_dt)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.config.control_dt)}

        # Indices looked up once (STYLE.md): joints, motors, pen, sensors.
        p = self.physics
        self._act_ids = p.hand_actuator_ids
        self._ctrl_max = self.model.actuator_ctrlrange[self._act_ids, 1].copy()
        self._hand_q = p.hand_qpos_ids
        self._hand_v = p.hand_dof_ids
        self._pen_q = p.pen_qpos_adr
        self._pen_v = p.pen_dof_adr
        self._pen_body = p.pen_body_id
        self._tip_sites = p.tip_site_ids
        self._key = self.model.key("grasp").id
        self._nominal_contact_x = np.array(self.hand.contact_x)
        self._warnings = self.data.warning.number  # a view: MuJoCo's warning counters
        # Views into MjData's fixed buffers, made once: each attribute access of the
        # bindings builds a new array (about 0.3 us, several per step).
        d = self.data
        self._qpos, self._qvel, self._ctrl = d.qpos, d.qvel, d.ctrl
        # The motors' ctrl as a view when they are consecutive (written in place), else
        # by index.
        self._act_ix = as_index(self._act_ids)
        self._hand_ctrl = self._ctrl[self._act_ix] if isinstance(self._act_ix, slice) else None
        # The hand's joints, the pen, the tips and their sensors: one read per step.
        self._reader = PenStateReader(self.model, d, p)
        self.disturbances = self._build_disturbances()
        self._reward_keys: tuple[str, ...] | None = None

        mujoco.mj_resetDataKeyframe(self.model, self.data, self._key)
        mujoco.mj_forward(self.model, self.data)
        self._start_episode()
        self.action_space = spaces.Box(-1.0, 1.0, shape=(p.n_hand_dofs,), dtype=np.float32)
        self._action_shape = self.action_space.shape
        obs_dim = len(self._observation())
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(obs_dim,), dtype=np.float64)
        #: The observation's parts in order, ``(name, size)`` each (:mod:`ias_gym.envs.layout`).
        self.observation_parts: ObservationParts = (
            *pen_observation_parts(len(self._hand_q), p.n_fingers),
            *self._task_observation_parts(),
        )
        #: Names to slices of the observation: ``obs[env.observation_layout["pen_axis"]]``.
        self.observation_layout = observation_layout(self.observation_parts)
        if layout_size(self.observation_parts) != obs_dim:
            raise RuntimeError(
                f"{type(self).__name__}'s observation parts {self.observation_parts} do not "
                f"cover its {obs_dim} columns"
            )
        self._renderer: Any = None

    # ------------------------------------------------------------------ task hooks
    def _sample_initial_pose(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(pen position [m], pen rpy [rad], contact x [m])`` for a reset (paper frame)."""
        cfg, rng = self.config, self.np_random
        return (
            rng.uniform(-cfg.pen_position_noise, cfg.pen_position_noise, 3),
            np.zeros(3),
            self._nominal_contact_x
            + rng.uniform(-cfg.contact_noise, cfg.contact_noise, self.physics.n_fingers),
        )

    def reference(self) -> PenReference:
        """The task's desired pen motion now (what an expert controller tracks)."""
        raise NotImplementedError

    def _task_update(self) -> None:
        """Update the task's per-step quantities from ``self.state`` (also at reset)."""

    def _task_observation(self) -> FloatArray:
        raise NotImplementedError

    def _task_observation_parts(self) -> ObservationParts:
        """The parts of :meth:`_task_observation`, in order (``(name, size)`` each)."""
        raise NotImplementedError

    def _task_reward(self) -> dict[str, float]:
        """Task reward terms (already weighted); the base adds contact and effort."""
        raise NotImplementedError

    def _task_success(self) -> bool:
        raise NotImplementedError

    def _task_info(self) -> dict[str, Any]:
        return {}

    # ------------------------------------------------------------------ disturbances
    def _build_disturbances(self) -> DisturbanceState | None:
        """Scale the simulated pen and prepare the episode disturbances (None: there are none)."""
        settings = DisturbanceSettings.from_config(self.config)
        if not settings.any:
            return None
        p, m = self.physics, self.model
        m.geom_friction[p.pen_geom_id, 0] *= settings.friction_scale
        m.body_mass[p.pen_body_id] *= settings.mass_scale
        m.body_inertia[p.pen_body_id] *= settings.mass_scale
        return DisturbanceState(
            settings, p.n_fingers, p.n_hand_dofs, self.config.control_dt, self.config.duration
        )

    @property
    def sensor_noise(self) -> SensorNoise | None:
        """This step's measurement noise (``None`` without sensor noise); see disturbances."""
        d = self.disturbances
        return d.noise if d is not None and d.settings.sensor_noise else None

    def internal_force_reference(self) -> FloatArray | None:
        """The task's internal-force offset ``f_int`` [N] now (``None``: no such reference)."""
        d = self.disturbances
        if d is None or not d.settings.internal_force_step:
            return None
        return d.internal_force_reference(self.time)

    def episode_metrics(self, info: dict[str, Any]) -> dict[str, float]:
        """The task's error metrics of a finished episode, from its last ``info``."""
        return {"max_position_error": float(info["max_position_error"])}

    # ------------------------------------------------------------------ gymnasium API
    @property
    def dt(self) -> float:
        """Control period [s]: one ``step`` (``frame_skip`` physics steps), as Gymnasium's
        MuJoCo envs have it."""
        return float(self.model.opt.timestep * self.frame_skip)

    @property
    def time(self) -> float:
        """Time since reset [s]."""
        return float(self.data.time)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[FloatArray, dict[str, Any]]:
        """Reset to a perturbed stable grasp.

        Args:
            seed: seeds ``self.np_random``.
            options: ``{"qpos": ..., "qvel": ...}`` starts from that exact MuJoCo state
                instead (e.g. a stored demonstration's initial state).
        """
        super().reset(seed=seed)
        mujoco.mj_resetDataKeyframe(self.model, self.data, self._key)
        options = options or {}
        if "qpos" in options:
            set_state_from_options(self.model, self.data, options)
        else:
            position, rpy, contact_x = self._sample_initial_pose()
            place_grasp(self.physics, position, rpy, contact_x, self.config.penetration)
        if self.disturbances is not None:
            self.disturbances.reset(self.np_random)
        self._start_episode()
        obs = self._observation()
        if self._reward_keys is None:  # the task's terms, once (not every reset)
            self._reward_keys = tuple(self._reward_terms())
        terms = dict.fromkeys(self._reward_keys, 0.0)
        if self.render_mode == "human":
            self.render()
        return obs, self._info(terms)

    def step(self, action: Any) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        """Apply normalised joint torques for ``control_dt``.

        Raises:
            ValueError: the action has the wrong shape or contains NaN or inf.
        """
        a = np.asarray(action, dtype=float)
        if a.shape != self._action_shape:
            raise ValueError(f"action must have shape {self._action_shape}, got {a.shape}")
        # One sum instead of isfinite(a).all(): NaN and inf propagate into it (cheaper).
        # (np.add.reduce is what ndarray.sum calls, without its Python-level wrapper.)
        if not math.isfinite(np.add.reduce(a)) and not np.isfinite(a).all():
            raise ValueError(f"action contains NaN or inf: {a}; actions must be finite")
        a = np.minimum(np.maximum(a, -1.0), 1.0)
        self._last_action = a
        m, d = self.model, self.data
        dist = self.disturbances
        if dist is not None:
            a = dist.actuate(a)
            push = dist.push(self.time)
            d.xfrc_applied[self._pen_body, :3] = push[TO_PAPER_INDEX] * (1.0, -1.0, 1.0)
        if self._hand_ctrl is not None:  # the motors' ctrl as a view: written in place
            np.multiply(a, self._ctrl_max, out=self._hand_ctrl)
        else:
            self._ctrl[self._act_ix] = a * self._ctrl_max
        # (a Python sum of the few counters costs a fifth of numpy's)
        warnings_before = sum(self._warnings.tolist())
        mujoco.mj_step(m, d, nstep=self.frame_skip)
        self._steps += 1
        if dist is not None:
            d.xfrc_applied[self._pen_body] = 0.0
            dist.draw_noise()

        # A diverging simulation makes MuJoCo warn (and reset its data).
        self._unstable = sum(self._warnings.tolist()) > warnings_before or not math.isfinite(
            float(np.add.reduce(self._qpos)) + float(np.add.reduce(self._qvel))
        )
        if self._unstable:
            mujoco.mj_resetDataKeyframe(m, d, self._key)
            mujoco.mj_forward(m, d)
        self._measure()
        state = self.state
        pos_err = state.position_error
        self._max_position_error = max(self._max_position_error, pos_err)
        self._dropped = pos_err > self.config.drop_distance
        self._gap = np.where(state.touching, 0.0, self._gap + self.config.control_dt)
        np.maximum(self._max_gap, self._gap, out=self._max_gap)
        self._task_update()

        obs = self._observation()
        terms = self._reward_terms()
        reward = float(sum(terms.values()))
        terminated = self._dropped and not self._unstable
        # The env ends its own episode at ``duration`` too, so a control_dt other than the
        # registered default still gets the documented episode length.
        truncated = self._unstable or self._steps >= self.max_steps
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, truncated, self._info(terms)

    # ------------------------------------------------------------------ pieces
    def _measure(self) -> None:
        """Read the step's measurements into ``self.state`` (:class:`PenStateReader`).

        The pen's and hand's state come from ``qpos``/``qvel`` (now); fingertip positions
        and contact sensors from the last forward pass, one physics step (1 ms) earlier.
        """
        self.state = self._reader.read()

    def _start_episode(self) -> None:
        """Zero the episode's statistics for the current (just reset) state."""
        self._steps = 0
        self._gap = np.zeros(self.physics.n_fingers)  # time without contact, per finger [s]
        self._max_gap = np.zeros(self.physics.n_fingers)
        self._max_position_error = 0.0
        self._dropped = False
        self._unstable = False
        self._last_action = np.zeros(self.physics.n_hand_dofs)
        self._measure()
        self._task_update()

    def _observation(self) -> FloatArray:
        state, noise = self.state, self.sensor_noise
        if noise is not None:
            joints, vector = state.joints.copy(), state.vector.copy()
            n = len(noise.qpos)
            joints[:n] += noise.qpos
            joints[n:] += noise.qvel
            vector[12:] += noise.force.ravel()
            return np.concatenate(
                [joints, vector, (self._steps / self.max_steps,), self._task_observation()]
            )
        return np.concatenate(
            [
                state.joints,  # the hand's joint angles and velocities at _measure
                state.vector,
                (self._steps / self.max_steps,),
                self._task_observation(),
            ]
        )

    def _reward_terms(self) -> dict[str, float]:
        terms = self._task_reward()
        a = self._last_action
        touching = int(np.count_nonzero(self.state.touching))
        terms["contact"] = self.config.contact_weight * touching / len(self.state.touching)
        terms["effort"] = -self.config.effort_weight * float(a @ a) / len(a)
        return terms

    def held(self) -> bool:
        """Whether the pen was held for the whole episode (the part of success every pen
        task shares): the time limit reached, never dropped, the simulation stable, the
        centre within ``max_position_error`` of nominal, no tip off for longer than
        ``max_contact_gap``."""
        return bool(
            self._steps >= self.max_steps
            and not self._dropped
            and not self._unstable
            and self._max_position_error < self.config.max_position_error
            and self._max_gap.max() <= self.config.max_contact_gap + 1e-9
        )

    def _info(self, terms: dict[str, float]) -> dict[str, Any]:
        success = self.held() and self._task_success()
        info = {
            "is_success": success,
            "time": self.time,
            "dropped": self._dropped,
            "sim_unstable": self._unstable,
            "max_position_error": self._max_position_error,
            "max_contact_gap": self._max_gap.copy(),
            "fingers_in_contact": self.state.touching.copy(),
        }
        for name, value in terms.items():
            info["reward_" + name] = value
        info.update(self._task_info())
        return info

    # ------------------------------------------------------------------ rendering, pickling
    def render(self) -> NDArray[Any] | None:
        """Render with the configured camera (``rgb_array``/``depth_array``) or a window.

        Raises:
            InputError: ``render_mode="human"`` where no window can be opened
                (:func:`check_window_possible`).
        """
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass one to gym.make")
            return None
        if self._renderer is None:
            if self.render_mode == "human":
                check_window_possible()  # again: the environment may have changed since
            from gymnasium.envs.mujoco.mujoco_rendering import MujocoRenderer

            self._renderer = MujocoRenderer(
                self.model,
                self.data,
                width=self.config.render_width,
                height=self.config.render_height,
                camera_name=None if self.render_mode == "human" else self.config.camera,
            )
        result: NDArray[Any] | None = self._renderer.render(self.render_mode)
        return result

    def close(self) -> None:
        """Release the renderer."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self) -> dict[str, Any]:
        """Pickle the configuration, the full MuJoCo state and the episode's statistics."""
        return {
            "config": dataclasses.asdict(self.config),
            "render_mode": self.render_mode,
            "mj_state": integration_state(self.model, self.data),
            "episode": {k: getattr(self, k) for k in self._episode_fields},
            "np_random": self._np_random,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Rebuild the env from its configuration and restore the pickled state."""
        type(self).__init__(self, render_mode=state["render_mode"], **state["config"])
        restore_integration_state(self.model, self.data, state["mj_state"])
        for key, value in state["episode"].items():
            setattr(self, key, value)
        self._np_random = state["np_random"]
        self._measure()
