"""ias-gym: dextrous in-hand manipulation after "Dextrous Sensor Hand for the IAS".

``import ias_gym`` registers the environment ids (string entry points, so nothing heavy
is imported until ``gym.make``).
"""

from ias_gym.registration import register_envs

__version__ = "0.1.0"

register_envs()

__all__ = ["__version__"]
