"""Registration of the ``IAS-*`` environment ids with Gymnasium (lazy string entry points)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

#: id -> (entry point, max_episode_steps at the default control_dt of 10 ms).
ENV_SPECS: dict[str, tuple[str, int]] = {
    "IAS-PenSlide-v0": ("ias_gym.envs.pen_slide:PenSlideEnv", 475),
    "IAS-PenRotate-v0": ("ias_gym.envs.pen_rotate:PenRotateEnv", 400),
    "IAS-PenRotate3F-v0": ("ias_gym.envs.pen_rotate:PenRotateEnv", 400),
    "IAS-PenRotate-Shadow-v0": ("ias_gym.envs.pen_rotate:PenRotateEnv", 400),
    "IAS-PenRotate-LEAP-v0": ("ias_gym.envs.pen_rotate:PenRotateEnv", 400),
    "IAS-GloveGrasp-v0": ("ias_gym.envs.glove_grasp:GloveGraspEnv", 400),
    "IAS-PenSkill-v0": ("ias_gym.envs.pen_skill_env:PenSkillEnv", 300),
    "IAS-GloveAssist-v0": ("ias_gym.envs.glove_assist:GloveAssistEnv", 400),
}
#: The keyword arguments an id passes to its entry point (its defaults; ``gym.make`` kwargs
#: override them): the other hands' ids are the same tasks on another ``hand`` (``"ias3f"``,
#: ``"shadow"``, ``"leap"``).
ENV_KWARGS: dict[str, dict[str, Any]] = {
    "IAS-PenRotate3F-v0": {"hand": "ias3f"},
    # the Shadow hand's measured tilt envelope (HandSpec.max_tilt) is 0.15 rad
    "IAS-PenRotate-Shadow-v0": {"hand": "shadow", "amplitude": 0.15},
    # the LEAP hand's is 0.075 rad
    "IAS-PenRotate-LEAP-v0": {"hand": "leap", "amplitude": 0.075},
}
#: Envs that need a device (a glove on a CAN bus, or its emulator): same layout.
HARDWARE_ENV_SPECS: dict[str, tuple[str, int]] = {
    "IAS-GloveHardware-v0": ("ias_gym.hardware.env:GloveHardwareEnv", 400),
}


def register_envs() -> None:
    """Register every ``IAS-*`` id once; calling again is harmless."""
    for env_id, (entry_point, max_steps) in {**ENV_SPECS, **HARDWARE_ENV_SPECS}.items():
        if env_id not in gym.registry:
            gym.register(
                id=env_id,
                entry_point=entry_point,
                max_episode_steps=max_steps,
                kwargs=ENV_KWARGS.get(env_id, {}),
                # a live glove is a person: the same seed does not give the same readings
                nondeterministic=env_id in HARDWARE_ENV_SPECS,
            )
