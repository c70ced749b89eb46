"""ias_gym.sim."""
