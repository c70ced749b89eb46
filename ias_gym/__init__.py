"""ias-gym: dextrous in-hand manipulation after "Dextrous Sensor Hand for the IAS".

``import ias_gym`` registers the environment ids (string entry points, so nothing heavy
is imported until ``gym.make``).
"""

from typing import Any

from ias_gym.registration import register_envs

__version__ = "0.1.0"

register_envs()

__all__ = ["__version__", "make_batched_vec"]


def __getattr__(name: str) -> Any:
    # ias_gym.make_batched_vec, imported on first use (the package import stays light)
    if name == "make_batched_vec":
        from ias_gym.runtime.vector_env import make_batched_vec

        return make_batched_vec
    raise AttributeError(f"module 'ias_gym' has no attribute {name!r}")
