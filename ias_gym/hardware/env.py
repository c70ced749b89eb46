"""IAS-GloveHardware-v0: IAS-GloveGrasp-v0 with the real glove on a CAN bus.

The virtual world, observation, action and reward are IAS-GloveGrasp-v0's
(:class:`~ias_gym.envs.glove_grasp.GloveGraspEnv`); the glove is a
:class:`~ias_gym.hardware.can_glove.CanGlove` opened once for the env's lifetime. Live, the
env runs in real time: every ``step`` first waits for its deadline (``control_dt`` apart,
:class:`~ias_gym.hardware.loop.LoopClock`), then reads the newest sample, calibrates it with
the person's profile, steps the world and sends the force display. A glove fault (the
watchdog: no valid sample for ``watchdog_timeout``) truncates the episode with the reason in
``info["fault"]``; ``reset`` re-enables the glove.

``record=PATH`` writes the session to a python-can log (an existing file is refused unless
``overwrite=True``: it may be the only recording of a person's session); ``replay=PATH``
plays such a log back (no bus, not paced) and reproduces the recorded observations exactly.
"""

from __future__ import annotations

import gc
from pathlib import Path
from typing import Any

from ias_gym.envs.glove_grasp import GloveGraspEnv
from ias_gym.errors import InputError
from ias_gym.glove.device import GloveDevice
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.profile import DEFAULT_GLOVE_ID, load_profile
from ias_gym.hardware.can_glove import CanGlove, check_record_path
from ias_gym.hardware.loop import LoopClock
from ias_gym.hardware.replay import ReplayGlove


class GloveHardwareEnv(GloveGraspEnv):
    """The glove-driven pinch-and-lift of IAS-GloveGrasp-v0 with a CAN glove
    (``IAS-GloveHardware-v0``).

    ## Description
    :class:`~ias_gym.envs.glove_grasp.GloveGraspEnv`'s world driven by a real glove on a CAN
    bus (:class:`~ias_gym.hardware.can_glove.CanGlove`, opened once for the env's
    lifetime), or by a recorded session played back (``replay``). Live, every ``step``
    first waits for its deadline (``control_dt`` apart), then reads the newest sample.

    ## Action Space
    As IAS-GloveGrasp-v0: ``Box(-1, 1, (10,))`` joint-target offsets.

    ## Observation Space
    As IAS-GloveGrasp-v0: ``(39,)`` float64. By name: ``env.unwrapped.observation_layout[name]``
    is the part's slice (:data:`~ias_gym.envs.glove_world.OBSERVATION_PARTS` in order):

    | name | size | content |
    |---|---|---|
    | ``joint_angles`` | 10 | hand joint angles [rad], ``JOINT_NAMES`` order |
    | ``joint_velocities`` | 10 | their velocities [rad/s] |
    | ``pen_position`` | 3 | pen centre relative to its start, world frame [m] |
    | ``pen_quat`` | 4 | pen orientation quaternion (w, x, y, z), world frame |
    | ``pen_velocity`` | 3 | pen centre velocity, world frame [m/s] |
    | ``pen_omega`` | 3 | pen angular velocity, world frame [rad/s] |
    | ``feedback_torques`` | 5 | force display on ``ACTUATED_JOINTS`` [N m] |
    | ``time`` | 1 | episode time [s] |

    ## Rewards
    As IAS-GloveGrasp-v0: ``lift``, ``pinch`` and ``effort``.

    ## Starting State
    As IAS-GloveGrasp-v0, from the glove's newest sample; ``reset`` re-enables the glove
    (clearing a watchdog fault).

    ## Episode End
    As IAS-GloveGrasp-v0; in addition an episode is truncated when the glove reports a fault
    (``info["fault"]`` non-empty, e.g. the watchdog: no valid sample for
    ``watchdog_timeout``).

    ## Arguments
    ``render_mode``, the fields of :class:`~ias_gym.envs.glove_grasp_config.GloveGraspConfig` (as
    IAS-GloveGrasp-v0), and (see :meth:`__init__`): ``interface`` [``"virtual"``],
    ``channel`` [``"ias-glove"``] and ``bus_kwargs``: the python-can bus; ``profile``: the
    wearer's calibration profile (JSON); ``fd`` [False]: CAN FD sensor frames;
    ``watchdog_timeout`` [0.02 s]: the host-side watchdog; ``glove_id``: the glove's id;
    ``record`` and ``replay``: a python-can session log to write or to play back;
    ``overwrite`` [False]: let ``record`` replace a file; ``realtime`` [live yes, replay
    no]: pace steps at ``control_dt`` in wall-clock time.

    ## Version History
    - v0: first version.
    """

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        interface: str = "virtual",
        channel: str | int = "ias-glove",
        bus_kwargs: dict[str, Any] | None = None,
        profile: str | Path | None = None,
        fd: bool = False,
        watchdog_timeout: float = 0.02,
        glove_id: str = DEFAULT_GLOVE_ID,
        record: str | Path | None = None,
        replay: str | Path | None = None,
        overwrite: bool = False,
        realtime: bool | None = None,
        **config: Any,
    ) -> None:
        """Open the glove and build the world.

        Args:
            render_mode: ``None`` or ``"rgb_array"``.
            interface, channel, bus_kwargs: the bus (``can.Bus(interface=..., channel=...,
                **bus_kwargs)``); any python-can backend.
            profile: the wearer's calibration profile (JSON, ``ias-gym calibrate``); its
                person id picks the hand model. Default: the simulated person
                ``config["person_id"]``'s cached calibration (for the emulator).
            fd: CAN FD sensor frames.
            watchdog_timeout: host-side watchdog [s].
            glove_id: the glove's id (the profile must be for it).
            record: write the session (every frame in and out) to this python-can log
                (``.asc``, ``.blf`` or ``.log``; written in full when the env closes).
            replay: play this recorded log back instead of opening a bus.
            overwrite: let ``record`` replace an existing file.
            realtime: pace steps at ``control_dt`` in wall-clock time (default: live yes,
                replay no).
            **config: fields of :class:`~ias_gym.envs.glove_grasp_config.GloveGraspConfig`.

        Raises:
            InputError: both ``record`` and ``replay``; a ``record`` file that exists (without
                ``overwrite=True``) or cannot be written; a ``replay`` file that is not a
                recorded session (:class:`~ias_gym.hardware.replay.ReplayError`); a bus that
                cannot be opened; a non-positive ``watchdog_timeout``. All are checked before
                a bus is opened, except the bus itself.
            ~ias_gym.glove.profile.ProfileError: a bad profile, or one for another glove.
        """
        if record is not None and replay is not None:
            raise InputError("record and replay exclude each other: give one of them")
        if record is not None:
            # first: a refused file must not cost a bus, a profile or a world
            check_record_path(record, overwrite=overwrite)
        calibration = None
        if profile is not None:
            loaded = load_profile(profile, glove_id=glove_id)
            config = {**config, "person_id": loaded.person_id}
            calibration = loaded.calibration
        person = PersonParams.sample(config.get("person_id", "p1"))
        device: GloveDevice
        if replay is not None:
            device = ReplayGlove(replay, fd=fd, glove_id=glove_id)
        else:
            device = CanGlove(
                interface,
                channel,
                fd=fd,
                watchdog_timeout=watchdog_timeout,
                glove_id=glove_id,
                log_path=record,
                overwrite=overwrite,
                **(bus_kwargs or {}),
            )
        self.device = device
        try:
            super().__init__(
                render_mode,
                person=person,
                calibration=calibration,
                glove_factory=lambda seed: device,
                **config,
            )
        except BaseException:
            device.close()
            raise
        self.realtime = replay is None if realtime is None else bool(realtime)
        self.clock = LoopClock(self.config.control_dt)

    def _open_glove(self, seed: int) -> GloveDevice:
        """The one device, re-enabled, with a sample newer than the enable.

        Live and paced, the glove is disabled (zero torque) between episodes, and the episode
        starts with the garbage collector's long-lived objects frozen (``gc.collect();
        gc.freeze()``): a full collection over them stops the whole interpreter for tens of
        milliseconds (40-57 ms measured after the test suite had built a few hundred thousand
        objects), longer than the glove's 20 ms watchdogs.
        """
        if self.realtime and isinstance(self.device, CanGlove):
            self.device.disable()
            gc.collect()
            gc.freeze()
        self.device.enable()
        if isinstance(self.device, CanGlove):
            self.device.wait_for_sample()
        self.clock.restart()
        return self.device

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        if self.realtime and self.glove is not None:
            self.clock.wait()
        return super().step(action)

    def close(self) -> None:
        super().close()
        self.device.close()
