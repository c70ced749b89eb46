"""ias_gym.envs."""
