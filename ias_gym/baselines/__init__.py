"""ias_gym.baselines."""
