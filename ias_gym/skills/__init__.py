"""ias_gym.skills."""
